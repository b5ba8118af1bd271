"""Where the tests find what they read: the repository's folders and the shared data beside
it (../shared/data, not part of the repository)."""
from pathlib import Path

TESTS = Path(__file__).resolve().parent
REPO = TESTS.parent
FLIGHTS = REPO / "flights"
BENCH = REPO / "bench"
DATA = TESTS / "data"
SHARED = REPO.parent / "shared" / "data"
