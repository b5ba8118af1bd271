"""`clip_counts`: where an autopilot's running clip totals rose."""
from mimunav.importers.clip_counts import SETTLE_S, clip_spans, merged


def test_rises_of_running_totals_are_spans_restarts_and_axes_counted():
    """Records every 0.1 s; per-axis totals (summed); a rise spans the record before it to
    SETTLE_S after its own; rises 0.1 s apart are one span; a total that falls (the
    autopilot restarted) counts from its new value, not as clips."""
    us = [0, 100_000, 200_000, 300_000, 400_000, 500_000, 600_000, 700_000]
    totals = [(0, 0), (0, 0), (3, 1), (3, 2), (3, 2), (0, 0), (0, 0), (5, 0)]
    settle = int(SETTLE_S * 1e6)
    assert clip_spans(us, totals) == [(100_000, 300_000 + settle, 5),
                                      (600_000, 700_000 + settle, 5)]
    assert clip_spans(us, [0] * len(us)) == []
    assert merged([(5, 9, 1), (0, 6, 2), (20, 30, 4)]) == [(0, 9, 3), (20, 30, 4)]
