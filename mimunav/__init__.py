"""mimunav: flight-test evaluation of MEMS IMUs (MIMU) against a FOG-IMU reference.

Data flows one way: profile -> truth -> sensors -> log -> compensation -> navigation ->
evaluation -> report. Conventions (see shared/spec/log-format.md): SI units, NED
navigation frame, body FRD, Hamilton quaternions scalar-first, q_nb maps body to NED.
"""
__version__ = "0.1.0"


def import_quaternion():
    """Import numpy-quaternion without the scipy.interpolate import it makes only to pick
    spline rather than finite-difference calculus for its derivative and integral helpers
    (0.6-0.8 s of a command's start, and mimunav uses neither); the spline versions it would
    have picked are put back, and they import scipy.interpolate when called. A version that
    cannot be imported so is left to be imported plainly. Called by the CLI before a command
    that works with attitudes (the sys.modules entry it sets for the import's duration is
    process-wide: call it before starting threads)."""
    import sys
    if "quaternion" in sys.modules or "scipy.interpolate" in sys.modules:
        return
    sys.modules["scipy.interpolate"] = None         # `from scipy.interpolate import` fails
    try:
        import quaternion
        from quaternion import calculus
    except ImportError:
        for name in [m for m in sys.modules if m == "quaternion" or m.startswith("quaternion.")]:
            del sys.modules[name]
        return
    finally:
        if sys.modules.get("scipy.interpolate", 0) is None:
            del sys.modules["scipy.interpolate"]
    for name, spline in (("spline", "spline_evaluation"), ("derivative", "spline_derivative"),
                         ("antiderivative", "spline_indefinite_integral"),
                         ("indefinite_integral", "spline_indefinite_integral"),
                         ("definite_integral", "spline_definite_integral")):
        if hasattr(calculus, spline):
            for module in (calculus, quaternion):
                setattr(module, name, getattr(calculus, spline))

