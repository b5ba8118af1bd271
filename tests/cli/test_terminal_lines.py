"""What `mimunav diagnose` prints of the scan's excursions: the largest, and how many more."""
from mimunav.cli.diagnosis import SHOWN_EXCURSIONS, unexplained_lines


def _excursion(t0, z):
    return {"channel": "accel.z", "t0": t0, "t1": t0 + 2.0, "z": z, "size": 0.01 * z,
            "units": "m/s^2"}


def test_the_largest_excursions_are_shown_in_time_order_and_the_rest_counted():
    """68 excursions, the largest (z -109.5) late in the record: it is among the lines shown,
    which run in time order, and a last line counts the 58 not shown."""
    many = [_excursion(10.0 * k, 15.0 + 0.1 * k) for k in range(67)] + [_excursion(900.0,
                                                                                 -109.5)]
    lines = unexplained_lines(many)
    assert len(lines) == SHOWN_EXCURSIONS + 1
    assert any("z -109.5" in line for line in lines[:-1])
    times = [float(line.split("accel.z ")[1].split("-")[0]) for line in lines[:-1]]
    assert times == sorted(times)
    assert "58 more" in lines[-1]
    few = unexplained_lines(many[:3])
    assert len(few) == 3 and not any("more" in line for line in few)
