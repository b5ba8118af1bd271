"""Command-line interface: `mimunav <command> ...` (also `python -m mimunav`), one module per
command group; each handler parses, calls the library, prints.

    program      the parser of every command, exit statuses, the process's end
    options      argument types and option groups the commands share
    simulation   demo, simulate, unit, lab
    logs         info, compensate
    calibration  calibrate, calibration compare, noise, drift
    evaluation   replay, table, budget, windows, reproduce, campaign
    diagnosis    diagnose
    importing    import
    reports      report
"""
from .program import build_parser, end_process, main, run

__all__ = ["build_parser", "end_process", "main", "run"]
