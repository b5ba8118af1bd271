"""A navigation-level finding beside the terms that level cannot test.

On a recording the regressors of the scale, cross-axis, misalignment and skew terms are made
of the MIMU's own outputs (`library.reads_own_outputs`): none of them is ever a finding
there (errors in variables, `navigation.OWN_NOISE`), yet the unit may carry them, and a
found term that looks like one of them takes its signature - a survey ship's MEMS 1.5 deg
off in yaw beside its INS had its lever arm found at 1.15 m [1.05, 1.26] where it was 1.5,
the verdict conclusive. Each finding is refitted beside each such term in turn, on the rows
its interval came from; its 95 % interval is widened about its estimate, one factor over
its components, until it holds each of those fits' intervals (`confirmation.judged_wider`:
set aside where it then holds zero or its held-out p fails its limit).
"""
import numpy as np

from . import inference, library
from .confirmation import judged_wider


def beside_untested(tier, cands, findings, noisy, held):
    """(kept, set aside) `findings` (of `cands` [(tier name, term, column)] on `tier`, matched
    on their labels) with their intervals widened beside the candidates `noisy` (term ->
    bool) names, each fitted with them on the rows `held` (module doc); each widened one
    carries {"term", "shift" (its coefficients' move, the fit's axes), "widened_by"} as
    "untested"."""
    column = {library.label(term): pos for _, term, pos in cands}
    given = [column[f["label"]] for f in findings]
    others = [(library.label(term), pos) for _, term, pos in cands
              if noisy(term) and pos not in given]
    if not findings or not others:
        return findings, []
    base = inference.fit(tier, given, held)
    alone = [(base.beta[base.slices[k]], base.interval(k)) for k in range(len(findings))]
    widest = [(1.0, None, None)] * len(findings)
    for label, pos in others:
        fit = inference.fit(tier, given + [pos], held)
        for k, (b0, (lo0, hi0)) in enumerate(alone):
            lo, hi = fit.interval(k)
            need = float(np.max(np.maximum(hi - b0, b0 - lo)
                                / np.maximum((hi0 - lo0) / 2, 1e-300)))
            if need > widest[k][0]:
                widest[k] = (need, label, fit.beta[fit.slices[k]] - b0)
    kept, aside = [], []
    for f, (factor, label, shift) in zip(findings, widest):
        if label is None:
            kept.append(f)
            continue
        ok, wide = judged_wider(f, factor, len(shift), f"beside {label}, {UNTESTED}",
                                "untested", {"term": label, "shift": shift.tolist()})
        (kept if ok else aside).append(wide)
    return kept, aside


UNTESTED = "a term made of the MIMU's own outputs that this level cannot test"
