"""A channel matrix in scratch files (`diagnosis.spill.ScratchMatrix`) reads as the array it
holds: rows a block at a time, columns whole, a selection of rows and columns; and the
wander's Grams from it are the array's, bit for bit."""
from pathlib import Path

import numpy as np
import pytest

from mimunav.diagnosis import wander
from mimunav.diagnosis.spill import ScratchMatrix


def _filled(x, block):
    spill, folder = ScratchMatrix.scratch()
    matrix = ScratchMatrix.empty(spill, folder, "channel0", x.shape[1])
    for a in range(0, len(x), block):
        matrix.append(x[a:a + block])
    matrix.close()
    return matrix


def test_a_scratch_matrix_reads_as_its_array():
    rng = np.random.default_rng(3)
    x = rng.normal(size=(1000, 6))
    matrix = _filled(x, 97)
    assert matrix.shape == x.shape
    for a, b in ((0, 1000), (0, 1), (95, 310), (999, 2000), (500, 500)):
        assert np.array_equal(matrix[a:b], x[a:b])
    assert np.array_equal(matrix[:, 2:5], x[:, 2:5])
    rows = rng.uniform(size=1000) < 0.7
    cols = [0, 2, 3, 5]
    picked = matrix.selected(rows, cols)
    assert picked.shape == (rows.sum(), 4)
    assert np.array_equal(picked[10:400], x[rows][:, cols][10:400])
    assert np.array_equal(picked[:, 1:3], x[rows][:, cols][:, 1:3])
    again = picked.selected(np.arange(len(picked)) % 3 == 0, [1, 3])    # of a selection
    assert np.array_equal(again[0:50], x[rows][:, cols][::3][:, [1, 3]][0:50])
    with pytest.raises(ValueError, match="read-only"):
        picked.append(np.zeros((1, 4)))
    with pytest.raises(IndexError):
        matrix[rows]
    with pytest.raises(IndexError):
        matrix[0:10:2]
    assert matrix[5:5].shape == (0, 6) and picked.selected(rows[:0] | False, [0]).shape[0] == 0
    widened = matrix.widened(1, 2)          # columns 1-2 copied at the end, after close()
    assert np.array_equal(widened[:, 6:8], x[:, 1:3])
    widened.append(x[:3, [0, 1, 2, 3, 4, 5, 1, 2]])     # appended to, not replaced
    assert len(widened) == 1003 and np.array_equal(widened[1000:], x[:3, [0, 1, 2, 3, 4, 5, 1, 2]])


def test_the_scratch_folder_goes_with_the_last_matrix_reading_it():
    spill, folder = ScratchMatrix.scratch()
    matrix = ScratchMatrix.empty(spill, folder, "channel0", 2)
    matrix.append(np.ones((4, 2)))
    matrix.close()
    picked = matrix.selected(np.array([True, False, True, True]), [1])
    path = Path(folder.name)
    del spill, folder, matrix
    assert path.is_dir() and np.array_equal(picked[0:3], np.ones((3, 1)))
    del picked
    assert not path.exists()


def test_the_grams_of_a_scratch_matrix_are_the_arrays(monkeypatch):
    rng = np.random.default_rng(4)
    n = 5000
    x = np.column_stack([np.cumsum(rng.normal(0, 0.1, n)) + rng.normal(size=n),
                         rng.normal(size=(n, 4))])
    present = rng.uniform(size=n) < 0.8
    monkeypatch.setattr(wander, "BLOCK_ROWS", 700)
    held = wander.grams(x, present, wander.LAMBDA_GRID)
    spilled = wander.grams(_filled(x, 333), present, wander.LAMBDA_GRID)
    assert np.array_equal(held[0], spilled[0]) and np.array_equal(held[1], spilled[1])
    assert held[2] == spilled[2] == present.sum() - 1
