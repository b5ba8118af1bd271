"""Flight logs in MCAP (`mimunav-log/1`, see shared/spec/log-format.md section 1):
a writer (context manager) and a streaming reader with a fast path for fixed-size channels."""
from .reader import FlightLog, LayoutError, LogError
from .writer import LogWriter

__all__ = ["FlightLog", "LayoutError", "LogError", "LogWriter"]
