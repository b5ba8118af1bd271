"""Forward selection of candidate terms on the training rows: Holm's step-down
thresholds over the library, the stated accuracies of the reference and the calibration added
for the terms they could make, physical ranges, encompassing tests between look-alikes (and
on the whole flight where the training half cannot tell them apart).
"""
import math

import numpy as np
from scipy import optimize

from . import library
from .fitting import (Fitter, plausible, reference_direction, shares_a_nuisance, term_test,
                      wald)


MAX_TERMS = 6


def _beyond(implausible, significant):
    """The `implausible` candidates' tests (`significant`: their fits and ranges), as
    `select` returns them beyond their physical range."""
    return [dict(j=j, b=significant[j]["b"], cov=significant[j]["cov"],
                 p_train=math.exp(significant[j]["logp"]), limit=significant[j]["limit"])
            for j in implausible]


# ---- selection on training rows ----------------------------------------------------------
def select(design, train, alpha, full_scale, whole=None):
    """Forward selection with Holm's step-down thresholds over the library; `whole`: a
    callable giving the all-rows `Fitter` (look-alikes the training rows cannot tell apart
    are compared on it, `told_apart`). Returns (chosen: [dict], within: linear terms
    significant but inside the reference's accuracy, beyond: [{j, b, cov, p_train, limit}]
    the candidates still significant when the selection stopped - nothing left to choose, or
    MAX_TERMS chosen -, given the terms chosen by then, whose estimate lies beyond
    their physical range - not chosen, never dropped silently: a mounting turned 30 deg fits
    its small-angle term at 0.40 rad, beyond 0.35; a lever arm signed wrong, 1.7 m)."""
    m = len(design.terms)
    chosen, excluded, within, beyond = [], set(), {}, []
    fitter = Fitter(design, train)
    for step in range(MAX_TERMS):
        current = [c["j"] for c in chosen]
        tests, implausible, significant = _step_tests(fitter, current, excluded, within, step,
                                                      alpha, full_scale)
        threshold = alpha / max(m - step, 1)
        passing = [j for j, r in tests.items() if r["logp"] <= math.log(threshold)]
        beyond = _beyond(implausible, significant)      # as the selection stops, said
        if not passing:
            break
        best, alternatives = _encompassing(fitter, current, passing, tests, threshold,
                                           full_scale)
        encompassed, named_on = [], "training half"
        if alternatives and whole is not None:
            before = best
            best, alternatives, encompassed = told_apart(whole(), current, best,
                                                          alternatives, threshold)
            named_on = "whole flight" if best != before else named_on
        best, set_aside = _whole_unit_or_one_axis(fitter, best, tests, significant,
                                                  threshold)
        alternatives = [j for j in alternatives if j != best]
        chosen.append(dict(j=best, alternatives=alternatives, named_on=named_on,
                           p_train=math.exp(tests[best]["logp"]), threshold=threshold,
                           b_train=tests[best]["b"],
                           implausible=[library.label(design.terms[j]) for j in implausible]))
        # a look-alike the whole flight tells apart without either explaining the other
        # away stays a candidate of the next step
        excluded |= {best, *alternatives, *encompassed, *set_aside}
    else:           # MAX_TERMS chosen: what lies beyond its range given all of them
        _, implausible, significant = _step_tests(fitter, [c["j"] for c in chosen], excluded,
                                                  dict(within), MAX_TERMS, alpha, full_scale)
        beyond = _beyond(implausible, significant)
    return chosen, [_within(design, j, r, full_scale) for j, r in within.items()
                    if j not in {c["j"] for c in chosen}], beyond


def _step_tests(fitter, current, excluded, within, step, alpha, full_scale):
    """(tests, implausible, significant) of a selection step given the terms `current`:
    each candidate's test with the stated accuracies where it beats them at the step's
    Holm threshold, those beyond their physical range (`significant` holds both, the latter
    with their `limit`); a linear term significant only without the stated accuracies is
    added to `within` with the accuracy it could be charged at."""
    design = fitter.design
    m = len(design.terms)
    tests, implausible, significant = {}, [], {}
    for j in range(m):
        if j in excluded or j in design.nuisance:
            continue
        res = term_test(fitter, current + [j], j)
        # a term must beat the stated accuracies (the reference's for a linear term, the
        # calibration's own for one the model carries) at the selection's threshold
        if res["logp_ref"] > math.log(alpha / max(m - step, 1)):
            if res["logp"] < math.log(alpha / m) and j not in within:
                within[j] = dict(res, charged_at=chargeable_accuracy(
                    fitter, current + [j], j, math.log(alpha / max(m - step, 1))))
            continue
        res = dict(res, logp=res["logp_ref"])
        significant[j] = res
        ok, limit = plausible(design, j, res["b"], full_scale)
        if not ok:
            implausible.append(j)
            significant[j] = dict(res, limit=limit)
            continue
        tests[j] = res
    return tests, implausible, significant


def _whole_unit_or_one_axis(fitter, best, tests, significant, level):
    """(chosen, [set aside]): a lever arm moves all three accelerometers by one vector; a
    proof-mass offset moves one. A lever arm is kept only when the size effect of at least
    two accelerometer axes passes this step on its own (`significant`: every candidate of
    the step with its p-value with the stated accuracies, a size effect beyond its physical
    range too - it still shows that its axis moves) - else the strongest plausible one
    (`tests`) replaces it and the lever arm is set aside (with one axis carrying it,
    the lever arm's fit of the other two is their small transfer errors, which a 3-channel
    Wald test turns into significance)."""
    design = fitter.design
    if design.terms[best]["effect"] != "lever_arm":
        return best, []
    alone = [j for j, term in enumerate(design.terms) if term["effect"] == "size_effect"
             and j in significant and significant[j]["logp"] <= math.log(level)]
    if len(alone) != 1 or alone[0] not in tests:
        return best, []
    return alone[0], [best]


def _encompassing(fitter, current, passing, tests, level, full_scale, contenders=10):
    """The chosen term among the passing candidates, and those it cannot be told from. The
    strongest alone is not enough (a linear term's Wald test and a slow term's likelihood
    ratio differ in kind): a contender replaces it when it stays significant given the
    current choice while the choice adds nothing given it (it encompasses the choice), both
    at the selection's own `level` (Holm's threshold of the step: telling look-alikes apart
    needs the same evidence as finding a term).
    Candidates that explain each other away are indistinguishable on the training half;
    among them the one of lowest order is named (`library.order`: a g-sensitivity before a
    g^2 term that mimics it at constant f_z), and among those of one order the one whose
    fitted size is the smallest share of its physical range (`library.physical_limit`: the
    likelier physics - a pull's pitch rate and normal load move together, and a 0.0069
    gyro cross-coupling of a calibrated unit had been named where a 1.9e-5 (rad/s)/(m/s^2)
    g-sensitivity, a tenth of its range, was hidden), the others listed - until the whole
    flight tells them apart (`told_apart`)."""
    design = fitter.design
    ranked = sorted(passing, key=lambda j: (tests[j]["logp"], -tests[j]["stat"]))[:contenders]
    log_level = math.log(level)

    def adds(j, given):
        return adds_to(fitter, current, j, given, log_level)
    best = ranked[0]
    for j in ranked[1:]:
        if adds(j, best) and not adds(best, j):
            best = j
    alike = [j for j in ranked if j != best and not adds(j, best) and not adds(best, j)]
    group = [best] + alike
    def share(j):                       # the fitted size over the term's physical range
        limit = library.physical_limit(design.terms[j], full_scale, design.calibrated,
                                       design.arm_given)
        return float(np.linalg.norm(tests[j]["b"])) / limit if np.isfinite(limit) else 0.0
    named = min(group, key=lambda j: (library.order(design.terms[j]), share(j),
                                      tests[j]["logp"]))
    return named, [j for j in group if j != named]


def told_apart(whole, current, named, alike, level):
    """(named, the look-alikes it still cannot be told from, those it encompasses) after the
    group is compared again on the whole flight (`whole`: the all-rows `Fitter`) by
    `_encompassing`'s pass at the same level: a member that adds to the named term while
    the named adds nothing to it replaces it; listed are the members where neither adds
    given the other. Half the flight may hold too little of what tells two terms apart - a
    g^2 term and a cross-coupling to the pitch rate coincide in a pull-up at constant speed
    and part only where the speed differs. The held-out rows take part in this choice, so
    their confirmation (`confirm_chosen`) confirms the group's signal, not which member is named:
    such a finding says so (`named_on`)."""
    log_level = math.log(level)

    def adds(j, given):
        return adds_to(whole, current, j, given, log_level)
    best = named
    for j in alike:
        if adds(j, best) and not adds(best, j):
            best = j
    others = [j for j in [named, *alike] if j != best]
    still = [j for j in others if not adds(j, best) and not adds(best, j)]
    return best, still, [j for j in others if adds(best, j) and not adds(j, best)]


def adds_to(fitter, current, j, given, log_level):
    """Candidate j is significant at log_level (its p with the stated accuracies) given the
    terms `current` and `given`."""
    return term_test(fitter, current + [given, j], j)["logp_ref"] <= log_level


def chargeable_accuracy(fitter, terms, j, log_level):
    """(k, monotone): the largest multiple k < 1 of the stated linear errors (the
    reference's and the calibration's together, the prior the test uses, for a term the
    reference's linear error can make; else the term's allowance, `Design.allowance`) at which candidate
    j, fitted with `terms`, passes the selection's test at `log_level`; 0.0 when no k down to
    1e-4 does (no reference a flight test has). Found on a log grid from k = 1 down and
    refined between the first grid point that passes and the one before; `monotone` is
    False when a smaller grid k fails again (the Wald statistic with a tighter prior need
    not grow: the wander level is chosen anew at each k)."""
    design = fitter.design
    if reference_direction(design, j) is not None:
        def logp(k):
            return wald(*fitter.fit(terms, accuracy=k).of(j))[1]
    else:
        res = term_test(fitter, terms, j)
        clocked = shares_a_nuisance(design, j)
        if res["logp"] > log_level or not (design.allowance[j].any() or clocked):
            return 0.0, True

        def logp(k):        # the clock's prior scaled too, where it is fitted beside j
            b, cov = fitter.fit(terms, clock=max(k, 1e-4)).of(j) if clocked else \
                (res["b"], res["cov"])
            return wald(b, cov + k ** 2 * design.allowance[j])[1]
    grid = np.logspace(0.0, -4.0, 25)
    passes = [logp(k) <= log_level for k in grid]
    if passes[0]:                        # passes as stated (a caller's other threshold)
        return 1.0, all(passes)
    if not any(passes):
        return 0.0, True
    first = passes.index(True)
    k = math.exp(optimize.brentq(lambda u: logp(math.exp(u)) - log_level,
                                 math.log(grid[first]), math.log(grid[first - 1]), xtol=1e-3))
    return k, all(passes[first:])


def _within(design, j, res, full_scale):
    """A term set aside (`term_test`'s logp_ref above the threshold): the stated 1 sigma along it
    - the reference's linear error (with the calibration's) for a term it can make
    (`reference_1sigma`), else the term's allowance (`Design.allowance`): the calibration's
    own (`calibration_1sigma`, a term the model carries) or the reference's gyro error through
    the lever-arm transfer (`transfer_1sigma`, a lever arm or proof-mass offset); and the
    reference's clock fitted beside it, under the import's 1 sigma (`clock_1sigma_s`,
    `design.add_clock_nuisance`) - and the 1
    sigma the test used (`total_1sigma`: the estimate's with the reference's prior, or the
    noise's plus the allowance, as `term_test` takes it) and the term's physical range
    (`physical_range`, `fitting.plausible`: a 1 sigma beyond it is a term the flight cannot
    identify)."""
    ref = reference_direction(design, j)
    if ref is not None:
        stated = {"reference_1sigma": np.sqrt(np.diag(ref)).tolist()}
        total = np.sqrt(np.diag(res["cov"]))
    else:
        key = "transfer_1sigma" if design.allowance_of[j] == "reference" else \
            "calibration_1sigma"
        stated = {key: np.sqrt(np.diag(design.allowance[j])).tolist()} \
            if design.allowance[j].any() or not shares_a_nuisance(design, j) else {}
        total = np.sqrt(np.diag(res["cov"]) + np.diag(design.allowance[j]))
    if shares_a_nuisance(design, j):    # the reference's clock, fitted beside it
        stated["clock_1sigma_s"] = [float(np.sqrt(v)) for v in design.nuisance.values()]
    k, monotone = res["charged_at"]
    return {"label": library.label(design.terms[j]), **_describe_b(res["b"]), **stated,
            "total_1sigma": total.tolist(),
            "physical_range": plausible(design, j, res["b"], full_scale)[1],
            "p_train": math.exp(res["logp"]),
            "charged_at_accuracy": k,
            "charged_at_1sigma": [k * v for v in next(iter(stated.values()))],
            "charged_at_monotone": monotone,
            "note": "significant against the noise alone, but not once the reference's and "
                    "the calibration's stated errors may share it: the data cannot tell it "
                    "from them (total_1sigma: the estimate's uncertainty with those priors), "
                    "so it cannot be charged to physics the model lacks. The MIMU and the "
                    "reference disagree along it; with those stated errors scaled by "
                    "charged_at_accuracy (1 sigma charged_at_1sigma; 0: not even 1e4 times "
                    "smaller) it would pass this test at the selection's threshold on the "
                    "training half - a finding would still need the plausibility, look-alike "
                    "and held-out checks"}


def _describe_b(b):
    return {"vector": b.tolist()} if len(b) > 1 else {"coefficient": float(b[0])}
