"""`flight.refuse_gaps`: only a gap the navigation would cross refuses it, and the cut it
suggests is one `mimunav cut` takes."""
from types import SimpleNamespace

import numpy as np
import pytest

from mimunav.flightlog import LogError
from mimunav.evaluation.flight import refuse_gaps


def _flight(t, start):
    return SimpleNamespace(mimu_t=t, initial=SimpleNamespace(t=start), path="drive.mcap")


def test_a_gap_before_the_navigations_start_refuses_nothing_and_the_cut_is_a_span():
    """A KITTI drive's IMU misses 1.92 s after its first stamp; its navigation starts at
    5.9 s: nothing to refuse (it had refused the navigation level, suggesting `--span
    0.000:0.000`, which cut refuses). The same gap after the start refuses it, naming the
    spans either side that hold samples."""
    t = np.r_[0.0, np.arange(1.92, 60.0, 0.01)]
    refuse_gaps(_flight(t, 5.9))
    with pytest.raises(LogError, match=r"--span 1\.920:59\.99[0-9] -o OUT$"):
        refuse_gaps(_flight(t, 0.0))
    later = np.r_[np.arange(0.0, 20.0, 0.01), np.arange(22.0, 60.0, 0.01)]
    with pytest.raises(LogError, match=r"--span 0\.000:19\.990 \(or 22\.000:59\.990\) -o OUT"):
        refuse_gaps(_flight(later, 5.9))
    refuse_gaps(_flight(later, 30.0))
