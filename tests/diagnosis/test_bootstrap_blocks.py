"""The block bootstrap's Wald statistics (`inference.wald_from_blocks`): a replicate that
draws too few distinct blocks to test a k-dimensional term is left out on its own. On a
90 s flight of 6 blocks, the quarter of the replicates that drew 3 or fewer had made every
replicate of a lever arm fail, and a lever arm right to 2 cm was never chosen."""
import numpy as np
from scipy import stats

from mimunav.diagnosis import inference


def _blocks(k=3, nb=6, per_block=40, seed=3):
    """(s, q) block sums of a k-column regression y = x beta + e over nb blocks."""
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(nb, per_block, k))
    y = x @ np.full(k, 0.3) + rng.normal(size=(nb, per_block))
    return np.einsum("bnk,bn->bk", x, y), np.einsum("bni,bnj->bij", x, x)


def _sandwich_wald(x, y, cluster):
    """The cluster-robust Wald statistic over k of least squares, written out from the
    rows (an independent form of the same statistic)."""
    beta = np.linalg.lstsq(x, y, rcond=None)[0]
    e = y - x @ beta
    bread = np.linalg.inv(x.T @ x)
    meat = sum(np.outer(x[cluster == c].T @ e[cluster == c], x[cluster == c].T @ e[cluster == c])
               for c in np.unique(cluster))
    return float(beta @ np.linalg.solve(bread @ meat @ bread, beta)) / x.shape[1]


def test_a_replicate_of_too_few_blocks_is_left_out_alone():
    s, q = _blocks()
    weights = np.array([[1, 1, 1, 1, 1, 1], [2, 2, 2, 0, 0, 0], [0, 3, 1, 0, 1, 1.0]])
    w = inference.wald_from_blocks(s, q, weights)
    assert np.isnan(w[1])                      # 3 distinct blocks: a 3-vector's scores
    assert np.all(np.isfinite(w[[0, 2]]))      # span 2 dimensions: no covariance
    assert stats.f.sf(w[0], 3, 5) < 0.05


def test_the_replicates_statistic_is_the_cluster_robust_wald():
    rng = np.random.default_rng(5)
    x = rng.normal(size=(6 * 40, 3))
    y = x @ np.array([0.2, -0.1, 0.3]) + rng.normal(size=len(x))
    cluster = np.repeat(np.arange(6), 40)
    s = np.array([x[cluster == b].T @ y[cluster == b] for b in range(6)])
    q = np.array([x[cluster == b].T @ x[cluster == b] for b in range(6)])
    w = inference.wald_from_blocks(s, q, np.ones((1, 6)))
    assert abs(w[0] / _sandwich_wald(x, y, cluster) - 1) < 1e-9
