"""The Kalman filter of the wander fitted block by block (`diagnosis.wander.grams`): the same
innovations as one pass over the record, whatever the blocks - so a long flight's Grams need
one block's memory."""
import numpy as np
import pytest

from mimunav.diagnosis import wander


@pytest.mark.parametrize("block", [1, 7, 64, 10_000])
def test_the_gram_by_blocks_is_the_gram_of_one_pass(monkeypatch, block):
    rng = np.random.default_rng(2)
    n = 3000
    cols = np.column_stack([np.cumsum(rng.normal(0, 0.1, n)) + rng.normal(0, 1, n),
                            rng.normal(size=(n, 3))])
    present = rng.uniform(size=n) < 0.6
    present[:150] = False               # whole blocks before the first present row
    present[1200:1700] = False          # a gap across block boundaries
    shape = rng.uniform(0.5, 2.0, n)
    monkeypatch.setattr(wander, "BLOCK_ROWS", block)
    for lam in (1e-9, 1e-3, 0.1):
        z, logdet = wander.innovations(cols, present, lam, shape)
        grams, logdets, count = wander.grams(cols, present, np.array([lam]), shape)
        gram, logdet_blocks = grams[0], float(logdets[0])
        assert count == len(z) == present.sum() - 1      # the diffuse first row gives none
        np.testing.assert_allclose(gram, z.T @ z, rtol=1e-12, atol=0)
        assert logdet_blocks == pytest.approx(logdet, rel=1e-12, abs=1e-9)
