"""`ph-explorer design --budget N [--data FILE.csv] [--effects FILE.py] [--json]`: which rings to
measure, in what order (ph_explorer/planning/ring_design.py): without data, N orientations that make the
catalog's effects identifiable and cover the data part; with a campaign, the next N rings that most
reduce the uncertainty of what it has measured; --decide, the rings that decide its diagnosis's
questions; --start and --next, an adaptive campaign's plans (ph_explorer/planning/adaptive.py)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.errors import InputError
from ph_explorer.geometry import DEFAULT_GEOMETRY, Geometry
from ph_explorer.io import checked_output_file
from ph_explorer.planning.deciding import DECIDE_BUDGET
from ph_explorer.planning.plans import Answer


def design_command(
    budget: int | None,
    json_output: bool = False,
    data: Path | None = None,
    effects: Path | None = None,
    geometry: dict[str, float] | None = None,
    decide: bool = False,
    out: Path | None = None,
    study: Path | None = None,
    start: bool = False,
    next_rings: bool = False,
    budget_minutes: float | None = None,
    tolerance_um: float | None = None,
    sigma_um: float | None = None,
    after: Path | None = None,
) -> int:
    """Print the proposed rings in measuring order, as text or one JSON object."""
    catalog = DEFAULT_CATALOG.with_file(effects) if effects is not None else DEFAULT_CATALOG
    if budget is not None and budget < 1:
        raise InputError(f"must be at least 1, got {budget}", option="--budget")
    adaptive = {"--budget-minutes": budget_minutes, "--tolerance-um": tolerance_um, "--sigma-um": sigma_um, "--after": after}
    if start or next_rings:
        if start and next_rings:
            raise InputError("plans either the first rings (--start) or the next ones (--next with --data), not both", option="--start")
        if decide or budget is not None:
            raise InputError("--start and --next plan their own rings: give --budget-minutes, not --budget or --decide", option="--budget")
        if study is not None:
            raise InputError("is for --decide: an adaptive campaign's plan reads the campaign alone", option="--study")
        return plan_command(start, data, catalog, json_output, geometry, out, adaptive)
    given = [option for option, value in adaptive.items() if value is not None]
    if given:
        raise InputError("is for an adaptive campaign: give --start, or --next with --data", option=given[0])
    if decide:
        return decide_command(DECIDE_BUDGET if budget is None else budget, data, catalog, json_output, geometry, out, study)
    if study is not None:
        raise InputError("is for --decide: the rings that decide what the study's diagnosis leaves open", option="--study")
    if out is not None:
        raise InputError("writes the rings of --decide only", option="--out")
    if budget is None:
        raise InputError("how many rings to propose: give --budget N (or --decide with --data)", option="--budget")
    # Imported when the command runs: the design reads the hybrid's bases, whose module loads torch.
    from ph_explorer.io import read_campaign
    from ph_explorer.planning.ring_design import propose_rings

    campaign = read_campaign(Path(data), geometry or {}) if data is not None else None
    try:
        shape = Geometry(**{**DEFAULT_GEOMETRY.as_dict(), **(geometry or {})})
    except ValueError as error:
        raise InputError(str(error), option="--pivot-to-ball-mm") from error
    report: dict[str, Any] = propose_rings(budget, geometry=shape, catalog=catalog.values(), measured=campaign).as_dict()
    report = {"budget": budget, "data": None if data is None else Path(data).name, **report}
    if json_output:
        print(json.dumps(report, allow_nan=False))
    else:
        print(design_text(report), end="")
    return 0


def design_text(report: dict[str, Any]) -> str:
    """One ring a line, in measuring order, then what the criterion says."""
    if report["data"] is None:
        head = f"{report['budget']} rings to measure, in this order ({report['candidates']} reachable candidates):"
    else:
        head = f"the next {report['budget']} rings after the {report['measured']} of {report['data']} ({report['candidates']} candidates left):"
    lines = [head, f"{'order':>5}  {'A0 deg':>7}  {'B0 deg':>7}  {'information gain':>16}  {'nearest ring deg':>16}"]
    for order, (a, b), gain, near in zip(report["order"], report["orientations"], report["gain"], report["nearest_deg"]):
        lines.append(f"{order:>5}  {a:>7g}  {b:>7g}  {gain:>16.2f}  {near:>16.1f}")
    lines.append(f"criterion: {report['criterion']}; log det {report['log_det']:.2f} over {report['columns']} directions")
    lines.append(f"effects designed for: {len(report['effects'])} instances")
    if report["not_designed_for"]:
        lines.append("not designed for: " + "; ".join(report["not_designed_for"]))
    return "\n".join(lines) + "\n"


def decide_command(
    budget: int,
    data: Path | None,
    catalog: Any,
    json_output: bool,
    geometry: dict[str, float] | None,
    out: Path | None,
    study: Path | None = None,
) -> int:
    """design --decide: the campaign diagnosed (as diagnose does; from the study's chain with
    --study, as diagnose --resume does), then the rings that decide its questions
    (planning.deciding)."""
    if data is None:
        raise InputError("needs the campaign whose diagnosis is to be decided: give --data FILE.csv", option="--decide")
    if out is not None:
        out = checked_output_file(out, "--out", "the rings", "rings.csv")
    from ph_explorer.diagnosis import diagnose
    from ph_explorer.figures.decision_text import decision_words
    from ph_explorer.io.rings import rings_csv_text
    from ph_explorer.io.writer import atomic_write
    from ph_explorer.models.lattice_need import read_lattice_campaign
    from ph_explorer.planning.deciding import rings_that_decide

    campaign = read_lattice_campaign(data, geometry)
    start = []
    if study is not None:
        from ph_explorer.diagnosis.study import Study
        from ph_explorer.io.files import file_sha256

        previous = Study.load(Path(study), catalog)
        start = previous.effects(catalog)
        previous.rings_added_on(file_sha256(Path(data)), str(data), campaign.scenario.get("merges", []))
    result = diagnose(campaign, catalog=catalog, start=start)
    decision = rings_that_decide(campaign, result, catalog, budget)
    if out is not None and decision.rings:
        atomic_write([(Path(out), rings_csv_text(decision.rings))])
    report = {"data": Path(data).name, "verdict": result.verdict, "budget": budget, **decision.as_dict()}
    if json_output:
        print(json.dumps(report, allow_nan=False))
        return 0
    words = decision_words(decision, budget).lines()
    lines = [f"{Path(data).name}: verdict {result.verdict}; " + words[0], *words[1:]]
    lines = with_out(lines, out, bool(decision.rings))
    print("\n".join(lines))
    return 0


def plan_command(
    start: bool,
    data: Path | None,
    catalog: Any,
    json_output: bool,
    geometry: dict[str, float] | None,
    out: Path | None,
    options: dict[str, Any],
) -> int:
    """design --start / --next (planning.adaptive): the first rings of a head with no data, or the
    next rings of a measured campaign (diagnosed first, as planning.adaptive.plan_diagnosis does), or the stop."""
    budget, tolerance, sigma, after = (options[k] for k in ("--budget-minutes", "--tolerance-um", "--sigma-um", "--after"))
    for value, option in ((budget, "--budget-minutes"), (tolerance, "--tolerance-um"), (sigma, "--sigma-um")):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise InputError(f"must be a positive number, got {value:g}", option=option)
    if out is not None:
        out = checked_output_file(out, "--out", "the rings", "rings.csv")
    from ph_explorer.io.rings import rings_csv_text
    from ph_explorer.io.writer import atomic_write
    from ph_explorer.planning import adaptive

    if start:
        if data is not None or after is not None:
            raise InputError(
                "plans a head with no data: to plan from a measured campaign give --next", option="--data" if data else "--after"
            )
        try:
            shape = Geometry(**{**DEFAULT_GEOMETRY.as_dict(), **(geometry or {})})
        except ValueError as error:
            raise InputError(str(error), option="--pivot-to-ball-mm") from error
        plan = adaptive.first_rings(budget, shape, sigma or adaptive.TP20_SIGMA_UM, catalog=catalog, tolerance_um=tolerance)
    else:
        if data is None:
            raise InputError("plans from a measured campaign: give --data FILE.csv (--start plans a head with no data)", option="--next")
        if sigma is not None:
            raise InputError("is for --start: with data the campaign's own repetitions say the noise", option="--sigma-um")
        from ph_explorer.models.lattice_need import read_lattice_campaign

        asked, previous = previous_plan(after) if after is not None else ((), None)
        campaign = read_lattice_campaign(data, geometry)
        result = adaptive.plan_diagnosis(campaign, catalog)
        plan = adaptive.next_rings(campaign, result, budget, catalog, asked=asked, tolerance_um=tolerance, previous=previous)
    report = plan.to_json()
    if out is not None and plan.rings:
        atomic_write([(Path(out), rings_csv_text(report["rings"]))])
    if json_output:
        print(json.dumps(report, allow_nan=False))
        return 0
    lines = plan.lines()
    lines = with_out(lines, out, bool(plan.rings))
    print("\n".join(lines))
    return 0


def previous_plan(path: Path) -> tuple[tuple[str, ...], Answer | None]:
    """The questions a previous plan's JSON (design --start/--next --json) says were asked, and the
    answer it read (None for a first plan's)."""
    from ph_explorer.io.csv_text import read_bytes

    name = str(path)
    try:
        report = json.loads(read_bytes(Path(path)).decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise InputError(f"not a plan's JSON (design --json writes one): {error}", file=name) from None
    questions = report.get("questions", []) if isinstance(report, dict) else None
    if not isinstance(questions, list) or not all(isinstance(q, str) for q in questions):
        raise InputError("its questions must be a list of strings", file=name, column="questions")
    answer = report.get("answer")
    if answer is None:
        return tuple(questions), None
    if not (isinstance(answer, dict) and isinstance(answer.get("words"), str) and type(answer.get("check_rings")) is int):
        raise InputError(
            'its answer must be {"words": text, "check_rings": a whole number, "named": [...]} or null', file=name, column="answer"
        )
    named = answer.get("named", [])
    if not (isinstance(named, list) and all(_named_entry(n) for n in named)):
        raise InputError('its answer\'s named must be a list of {"label": text, "untold": [text, ...]}', file=name, column="answer")
    return tuple(questions), Answer.from_json(answer)


def _named_entry(entry: object) -> bool:
    """One entry of a plan answer's named list: {"label": text, "untold": [text, ...]}."""
    if not isinstance(entry, dict) or not isinstance(entry.get("label"), str):
        return False
    untold = entry.get("untold")
    return isinstance(untold, list) and all(isinstance(u, str) for u in untold)


def with_out(lines: list[str], out: Path | None, any_ring: bool) -> list[str]:
    """The lines with what became of --out: the rings written to it, or no file when there is no ring."""
    if out is None:
        return lines
    if any_ring:
        return [*lines[:-1], f"{lines[-1]}; written to {out}"]
    return [*lines, f"No ring to measure: {out} not written."]
