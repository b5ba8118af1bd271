"""The project's error for bad input: a file, an option, a profile, a calibration or a fit
that cannot be used, said in one line. The command line reports these (and the operating
system's file errors) as the user's, with exit status 2; anything else is a bug in mimunav
and shows as one, with its traceback."""


class InputError(ValueError):
    """Input mimunav cannot use; the message says which and why."""


def warn(message):
    """A loud warning for something suspicious that does not stop the work: one line on
    standard error, prefixed like the command line's errors."""
    import sys
    print(f"mimunav: warning: {message}", file=sys.stderr)


def require(module, extra, purpose):
    """The imported `module`, an optional dependency; when it is not installed, an
    InputError in one line naming the extra that installs it (pip install 'mimunav[extra]')
    and what needs it (`purpose`)."""
    import importlib
    try:
        return importlib.import_module(module)
    except ImportError:
        raise InputError(f"{purpose} needs {module.split('.')[0]}, which is not installed: "
                         f"pip install 'mimunav[{extra}]'") from None
