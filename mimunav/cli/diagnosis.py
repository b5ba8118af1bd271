"""The diagnose command, and findings as the terminal shows them."""
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..importers.kinds import VEHICLES
from .options import LEVELS, SEED, probability


def _diagnose(args):
    """Diagnosis of a log against a calibration (sensor level with a reference IMU,
    navigation level with only a reference trajectory); JSON and report."""
    from ..files import refuse_inputs
    refuse_inputs([args.json, args.output], [args.log, args.model, args.noise])
    inside = args.json and args.output and \
        Path(args.output).resolve() in Path(args.json).resolve().parents
    if inside:
        raise InputError(f"--json {args.json} lies inside the report folder {args.output}, which "
                         "gets its own diagnosis.json: give -o alone, or --json elsewhere")
    if args.json and Path(args.json).exists() and not args.force:   # before the work
        raise FileExistsError(f"{args.json} exists; use --force to replace it")
    if not args.output:
        return _diagnosed(args, None)
    from ..reports.plots import Painter
    with Painter() as painter:              # forked now: matplotlib loads beside the work
        return _diagnosed(args, painter)


def _diagnosed(args, painter):
    """`_diagnose` once its arguments are checked; the report's figures by `painter`."""
    from ..compensation.calibration_file import with_found
    from ..diagnosis import levels
    from ..diagnosis.document import document, dumps
    from ..sensors.accuracy import Accuracy
    from ..files import refuse_folder_early, write_atomic
    from ..reports import diagnosis as report
    from ..reports.navigation_gain import model_navigation_beside
    if args.output:                 # here, after the fork: the child's import runs beside these
        refuse_folder_early(args.output, args.force, report.FILES)
    # a long flight's sensor level streams, its report's navigations too
    flight, cal, level, why = levels.load(args.log, args.model, args.level, args.vehicle,
                                          stream=True)
    accuracy = Accuracy.parse(args.reference_accuracy) if args.reference_accuracy else None
    noise = None
    if args.noise:
        if level != "sensor":
            raise InputError(f"--noise sets the bias tests of the sensor level; {args.log} is "
                             f"diagnosed at the {level} level, which has none")
        from ..reports.noise import load
        noise = load(args.noise)
        print(f"bias tests' normal wander: {noise['source']}")
    # the report's navigation of the model needs nothing the diagnosis finds: made when
    # the report asks for it (not on a thread beside the diagnosis: see its docstring)
    model = model_navigation_beside(flight, cal) if args.output else None
    diag = levels.diagnose(flight, cal, level, args.alpha, args.seed, accuracy, noise,
                           args.vehicle)
    diag.level_choice = why
    doc = document(args.log, diag, args.alpha)
    found = with_found(cal, doc["findings"])
    if args.output:
        report.write(args.output, doc, diag, flight, cal, found,
                     args.model or "identity (the log's /mimu/imu as recorded)", force=args.force,
                     painter=painter, model=model)
    if args.json:
        write_atomic(args.json, dumps(doc), force=args.force)
    if doc["conclusive"]:
        print(f"verdict: {doc['verdict']} ({doc['candidates_tested']} candidates)")
    else:
        print(f"verdict: inconclusive (contract verdict {doc['verdict']}; "
              f"{doc['candidates_tested']} candidates)")
        for reason in doc["inconclusive_reasons"]:
            print(f"  because {reason}")
    if doc.get("bins", {}).get("why"):
        print(f"  {doc['bins']['why']}")
    for line in grade_lines(doc):
        print(line)
    for f in doc["findings"]:
        print(finding_line(f))
    for why in doc.get("untested", []):
        print(f"  beside them, {why}")
    for line in clock_lines(doc.get("reference_clock")):
        print(line)
    lag = doc.get("time_lag", {})
    if "tau_s" in lag:
        interval = f"[{lag['ci95'][0] * 1e3:.1f}, {lag['ci95'][1] * 1e3:.1f}]"
        print(f"  time lag from the yaw rate: {lag['tau_s'] * 1e3:.1f} ms "
              + (f"{interval} (positive: the IMU lags)" if "not_a_finding" not in lag else
                 f"(positive: the IMU lags); not a finding, and its segments' interval "
                 f"{interval} no measure of it: {lag['not_a_finding']}"))
        for stray in lag.get("segments_set_aside", []):
            print(f"    a segment set aside: its lag {stray['lag_s'] * 1e3:+.1f} ms (standard "
                  f"error {stray['se_s'] * 1e3:.2g}) lies {abs(stray['z']):.0f} standard "
                  "deviations from the others': the vehicle model fails there")
    elif "not_estimated" in lag:
        print(f"  time lag from the yaw rate not estimated: {lag['not_estimated']}")
    for line in unexplained_lines(doc["unexplained"]):
        print(line)
    for line in left_out_lines(doc):
        print(line)
    for line in set_aside_excursion_lines(doc.get("reference_check", {})):
        print(line)
    for w in doc.get("within_reference_accuracy", []):
        print(set_aside_line(w))
    for line in not_confirmed_lines(doc):
        print(line)
    if args.output:
        print(f"wrote {args.output}/diagnosis.md" + (" and CAL+found.json" if found else ""))
    return 0


SHOWN_EXCURSIONS = 10      # the terminal's; the JSON and the report hold them all
LEFT_OUT = (("transfer_shocks_left_out", "the lever-arm transfer misses a shock"),
            ("clips_counted_left_out", "the IMU's own clip counter rose"),
            ("gaps_left_out", "an IMU misses samples (either IMU's stamps step over a gap)"),
            ("refuted_fixes_left_out", "a reference fix lay off the IMU's own forces (the "
                                       "fix left out of the track)"),
            ("rails_left_out", "an output sat at its extreme, bit for bit, where the "
                               "reference read beyond (a rail too short to name saturation)"))


def grade_lines(doc):
    """The terminal's line on a reference IMU whose default FOG grade its own data contradict
    (`diagnosis.reference_grade`: its source says so)."""
    for part in doc.get("reference_accuracy", {}).get("source", "").split("; "):
        if "FOG grade is contradicted" in part:
            yield f"  the reference IMU: {part}"


def left_out_lines(doc):
    """The terminal's lines of the spans the fit left out, and why (LEFT_OUT)."""
    for key, where in LEFT_OUT:
        spans = doc.get(key, [])
        if spans:
            yield (f"  left out of the fit: {len(spans)} span(s) where {where} ("
                   + ", ".join(f"{u['t0']:.1f}" + ("" if u["t1"] == u["t0"] else
                                                   f"-{u['t1']:.1f}") + " s" for u in spans[:5])
                   + (", ..." if len(spans) > 5 else "") + ")")


def set_aside_excursion_lines(check):
    """The terminal's lines of the excursions the track level's reference check set aside
    (`check`: the document's reference_check): on channels it does not predict, at fixes
    the IMU refuted, within the vehicle model's own errors."""
    for u in check.get("excursions_not_predicted", []):
        yield ("  on a channel the reference does not predict (says nothing of the IMU): "
               + excursion_text(u))
    for u in check.get("excursions_at_refuted_fixes", []):
        yield ("  at a reference fix left out (the reference's step, not the IMU's): "
               + excursion_text(u))
    for u in check.get("excursions_of_the_model", []):
        yield (f"  the vehicle model's own: {excursion_text(u)} within {u['bound']:.2g} "
               f"{u['units']}, {u['why']}")


def unexplained_lines(unexplained):
    """The terminal's lines of the scan's excursions: the SHOWN_EXCURSIONS largest |z| in time
    order, and how many more there are."""
    shown = sorted(sorted(unexplained, key=lambda u: -abs(u["z"]))[:SHOWN_EXCURSIONS],
                   key=lambda u: u["t0"])
    lines = [f"  unexplained residual {excursion_text(u)}" for u in shown]
    if len(unexplained) > len(shown):
        lines.append(f"  ... and {len(unexplained) - len(shown)} more unexplained residuals "
                     f"(the {len(shown)} of the largest |z| shown; all in the JSON and the "
                     "report)")
    return lines


def excursion_text(u):
    """An excursion of the scan: channel, span, robust z and its size (SI units)."""
    size = f", {u['size']:+.3g} {u['units']}" if "size" in u else ""
    return f"{u['channel']} {u['t0']:.1f}-{u['t1']:.1f} s (z {u['z']:.1f}{size})"


def finding_line(f):
    """A finding for the terminal: term, coefficient and units, 95 % interval, held-out p,
    attribution, a vector's components with the axes they are about (a mounting's turn also
    about the vehicle's axes, in degrees), and the terms this flight cannot tell it from
    (they explain the same residual: the name is the likelier of them, not a certainty)."""
    from ..diagnosis.inference import p_text
    units = "" if f["units"] == "1" else f" {f['units']}"
    line = (f"  {f['label']}: {f['coefficient']:.4g}{units} "
            f"[{f['ci95'][0]:.4g}, {f['ci95'][1]:.4g}] ("
            + ("its largest component, of a vector of size "
               f"{float(np.linalg.norm(f['vector'])):.4g}{units}; " if "vector" in f else "")
            + f"held-out p {p_text(f['p_heldout'])}"
            + (f", removes {f['effect_size']['heldout_variance_removed']:.2%} of the held-out "
               "residual variance as the fit weighs it" if "effect_size" in f else "")
            + f"; {f.get('attribution', 'navigation level')})")
    if "vector" in f:
        line += (f"\n    vector ({f['units']}, {f.get('frame', 'sensor')} axes x, y, z) "
                 + ", ".join(f"{v:.4g} [{lo:.4g}, {hi:.4g}]"
                             for v, (lo, hi) in zip(f["vector"], f["vector_ci95"])))
    if "vector_vehicle" in f:           # the mounting's turn: about the vehicle's x, y, z
        line += ("\n    the sensor turned about the vehicle's forward, right, down axes "
                 + ", ".join(f"{np.degrees(v):+.2f} deg [{np.degrees(lo):+.2f}, "
                             f"{np.degrees(hi):+.2f}]"
                             for v, (lo, hi) in zip(f["vector_vehicle"],
                                                    f["vector_vehicle_ci95"])))
    if "import_measured" in f:
        m = f["import_measured"]
        line += f"\n    the import measured {m['value']:.4g} {m['units']}: {m['basis']}"
    if "scale_alike" in f:
        from ..diagnosis.document import scale_alike_text
        line += "\n    " + scale_alike_text(f["scale_alike"])
    if "band_left_out" in f:
        from ..diagnosis.document import band_text
        line += "\n    " + band_text(f["band_left_out"])
    if "mounting_rpy_deg" in f:
        line += ("\n    the mounting that holds it (sensor -> vehicle roll, pitch, yaw): "
                 f"--mounting-rpy-deg {' '.join(f'{a:g}' for a in f['mounting_rpy_deg'])} "
                 "(import)")
    halves = f.get("halves")
    if isinstance(halves, dict) and halves["widened_by"] > 1:
        line += (f"\n    the recording's halves disagree (p {halves['p_same']:.2g}): interval "
                 f"widened {halves['widened_by']:.2f}x" + (
                     f", held-out p {p_text(halves['p_heldout_widened'])} with it"
                     if "p_heldout_widened" in halves else ""))
    untested = f.get("untested")
    if isinstance(untested, dict) and untested["widened_by"] > 1:
        from ..diagnosis.untested import UNTESTED
        line += (f"\n    beside {untested['term']}, {UNTESTED}: interval widened "
                 f"{untested['widened_by']:.2f}x")
    noise = f.get("errors_in_variables")
    if isinstance(noise, dict) and noise["widened_by"] > 1:
        line += (f"\n    the reference's own noise moves it (errors in variables): with as much "
                 f"again {_values(noise['noisier'])}, read back {_values(noise['read_back'])}"
                 f" (sensor axes): interval widened {noise['widened_by']:.2f}x")
    if isinstance(f.get("shifted"), dict):                   # a skew beyond the linear term
        line += f"\n    {f['shifted']['said']}"
    if f.get("ci95_method") == "student-t over segments":     # the track level's lag
        line += ("\n    its interval: the scatter of the yaw rate's segments' lags (Student t), "
                 "not the bins' noise model - the library check does not widen it")
    alike = [a["label"] for a in f.get("indistinguishable_from", [])]
    if alike:
        line += "\n    not told apart on this flight from " + ", ".join(alike)
    return line


def not_confirmed_lines(doc):
    """The terms chosen in training and then not confirmed, each with why, for the terminal
    (`document.not_confirmed_said`)."""
    from ..diagnosis.document import not_confirmed_said     # the numeric stack: not at start
    alone, again = not_confirmed_said(doc)
    return [f"  not confirmed: {label}: {why}" for label, why in alone] + (
        [f"  not confirmed, for a reason the diagnosis is inconclusive: {', '.join(again)}"]
        if again else [])


def clock_lines(clock):
    """The reference IMU's clock as the diagnosis read it (`document.clock_text`), for the
    terminal: [] where it was not fitted."""
    from ..diagnosis.document import clock_text
    if not clock:
        return []
    return [f"  {clock_text(clock)}"] + ([f"    {clock['latency']}"] if clock.get("latency")
                                         else [])


def set_aside_line(w):
    """A term set aside as within the stated accuracies (`within_reference_accuracy`), for
    the terminal: its value, its p against the noise alone, the reference's stated 1 sigma
    along it and the 1 sigma the test used - the estimate's with the reference's and the
    calibration's stated errors as priors, which can exceed both."""
    from ..diagnosis.document import charge_text, clock_words, stated_errors, stated_sigma
    value = w.get("coefficient", w.get("vector"))
    said = (f"{value:.4g}" if isinstance(value, float) else
            "[" + ", ".join(f"{v:.3g}" for v in value) + "]")
    sigmas = lambda key: ", ".join(f"{v:.3g}" for v in w[key])     # noqa: E731
    words, key = stated_errors(w)
    stated = (f"the reference's (1 sigma {sigmas(key)}) and the calibration's"
              if key == "reference_1sigma" else f"{words} (1 sigma {stated_sigma(w)})") \
        + clock_words(w)
    head = (f"  within the stated errors: {w['label']} {said}: significant against the "
            f"noise alone (p {w['p_train']:.2g}), not once the stated errors that may share "
            f"it - {stated} - are allowed: with them its 1 sigma is {sigmas('total_1sigma')}")
    tests_differ = w.get("charged_at_accuracy") == 0 and key != "reference_1sigma"
    if tests_differ:        # no smaller stated error lets it pass: not theirs to share
        head = (f"  set aside: {w['label']} {said}: its likelihood ratio against the noise "
                f"alone is significant (p {w['p_train']:.2g}), its estimate's Wald test is not "
                f"(1 sigma {sigmas('total_1sigma')}), with {words} as stated or 1e4 times "
                "smaller: the two tests disagree on this flight - not a finding")
    if max(w["total_1sigma"]) > w.get("physical_range", float("inf")):
        head += (f", beyond its physical range {w['physical_range']:.3g}: the flight cannot "
                 "identify it")
    option = ("; where the reference's errors are known better, --reference-accuracy "
              "states them" if key == "reference_1sigma" else "")
    return head if tests_differ else f"{head}\n    {charge_text(w)}{option}"


def add_diagnose(sub):
    """The `diagnose` command's parser."""
    p = sub.add_parser("diagnose", help="find the physics the model leaves out: test the "
                       "MIMU's residual against the reference IMU (or, without one, its "
                       "navigation error against the reference trajectory) for every term of "
                       "the effect vocabulary (log contract section 3)")
    p.add_argument("log", help="flight log (MCAP) with /mimu/raw or /mimu/imu, and /fog/imu "
                   "(sensor level) or /truth/state (navigation and track levels)")
    p.add_argument("--level", choices=LEVELS, default="auto",
                   help="sensor: MIMU outputs (m/s^2, rad/s) against the FOG-IMU's; navigation: "
                   "NED velocity error (m/s) against /truth/state; track: MIMU outputs against "
                   "the ideal IMU simulated along a car's /truth/state without attitude (a "
                   "recording); auto (default): sensor with /fog/imu; for a recording, "
                   "navigation when its reference has an attitude, track when a car carried "
                   "the IMU (declared, or judged from the track: --vehicle), else navigation "
                   "(whose findings need a measured initial heading)")
    p.add_argument("--model", help="the calibration the user believes (mimunav-calibration/1); "
                   "required for /mimu/raw, optional for a recorded /mimu/imu (identity)")
    p.add_argument("--json", help="write the mimunav-diagnosis/1 document here (with -o: the "
                   "report's diagnosis.json, whose `navigation` section - the MIMU navigated "
                   "with and without the found terms - only a report computes). Without -o, "
                   "the sensor level of a long log (over ~1 M MIMU samples) is read from it "
                   "block by block in bounded memory, its per-sample columns (~200 bytes a "
                   "sample) in scratch files under the temporary directory (TMPDIR)")
    p.add_argument("-o", "--output", help="report folder: diagnosis.md, plots, diagnosis.json, "
                   "CAL+found.json (the model with the found terms); the log is held in "
                   "memory for the report's navigations")
    p.add_argument("--alpha", type=probability, default=0.05,
                   help="family-wise error rate over the candidate library, 0 < alpha < 1 "
                   "(default 0.05)")
    p.add_argument("--reference-accuracy", metavar="KEY=VALUE,...",
                   help="the reference IMU's 1-sigma accuracy; the keys given override the log's "
                   "sensor/fog `accuracy` metadata, which overrides the defaults (seed S1 Table "
                   "4: scale 2.5e-4, misalignment 1e-4 rad (assumed), bias 1 deg/h and 100 ug; "
                   "a recording's logging steps measured from its outputs): gyro_scale, "
                   "accel_scale (1), gyro_misalignment_rad, accel_misalignment_rad (rad), "
                   "gyro_bias (rad/s), accel_bias (m/s^2) - bias stability -, gyro_step "
                   "(rad/s), accel_step (m/s^2) - the step its outputs were logged in. A bias "
                   "beyond Table 4's makes the reference MEMS-grade: whatever it may carry "
                   "itself is charged to 'mimu-or-reference'")
    p.add_argument("--noise", metavar="NOISE.json",
                   help="the unit's measured random errors (a `mimunav noise` file of its "
                   "/mimu/raw or /mimu/imu at rest): its bias instability B (SI) replaces the "
                   "class's zero drift as the wander the sensor level's bias tests take as "
                   "normal")
    p.add_argument("--vehicle", choices=VEHICLES,
                   help="what carried the IMU, over the recording's metadata (default: as "
                   "imported, else judged from the track): the track level is a car's")
    p.add_argument("--seed", type=SEED, default=0, help="seed of the navigation level's block "
                   "bootstrap (the sensor and track levels draw nothing)")
    p.add_argument("--force", action="store_true", help="replace existing outputs")
    p.set_defaults(func=_diagnose)


def _values(x):
    """A coefficient or a vector's components, for a line of text."""
    return ", ".join(f"{v:.4g}" for v in np.atleast_1d(x))
