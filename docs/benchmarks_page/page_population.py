"""The benchmarks page's `## Population` section (`population`, `verdict_speed`), and the population's verdict
rates that docs/hooks.py writes into diagnosis.md in place of VERDICT_RATES_MARKER.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from .page_format import get, holds, joined, num, pct, share_of, table

POPULATION_INTRO = """\
## Population

`population`: the verdicts over a population of random heads (`ph-explorer simulate
--random-head`; distributions and designs in [Random heads](methods/random_heads.md)), each
diagnosed as a user would with the default catalog (a claim's gain tested on rings left out of the
choice, the nested cross-validation, before the verdict). Healthy heads: any verdict but `none` is a false alarm, unless it names only the
head's own background terms at their true settings (a true finding of a term the lattice model
leaves, e.g. a 4/rev B-axis error a 20 deg lattice cannot follow); both shares are shown.
Stability: the same heads with another draw of their noise. One catalog effect at 1-3x its
detection limit: `missing` or `partial` with it (at its settings, or at settings the diagnosis
cannot exclude; beside it, found at its true setting, and how many others each find keeps) or
with a claim whose confounded partner it is, named at its settings, and its true parameters within the fit +- U (per parameter, as k = 2 is stated; all of
an effect's parameters at once beside it). One effect of a shape no catalog holds (a local
defect of an axis, seven lobes of the probe) at 2-4x its detection limit: how often it is called
`missing` (an overclaim), and, where the diagnosis sees it, whether the signature's first
variable is of the defect's own joint (b_joint_deg or b0_deg for a B defect), the exact variable,
and a bump within two widths of the defect. Intervals are 95 % Clopper-Pearson.
"""


def not_excluded_text(spread: Mapping[str, Any] | None) -> str:
    """'other settings not excluded per find: median 0, 90th percentile 3, max 19'."""
    if not spread or spread.get("median") is None:
        return ""
    return f"other settings not excluded per find: median {spread['median']:g}, 90th percentile {spread['p90']:g}, max {spread['max']}"


def population(results: Mapping[str, Any]) -> str:
    pop = results.get("population", {})
    healthy = pop.get("healthy") or {}
    rows = [
        [
            "healthy heads: false alarms",
            share_of(healthy.get("false_alarm")),
            joined([f"{k} {v}" for k, v in (healthy.get("verdicts") or {}).items()]),
        ],
        ["healthy heads: any verdict but none", share_of(healthy.get("any_verdict_but_none")), ""],
        ["healthy heads: naming only their own background terms", share_of(healthy.get("true_background_findings")), ""],
        *[[f"healthy heads, {d} design: false alarms", share_of(x), ""] for d, x in (healthy.get("by_design") or {}).items()],
        ["healthy heads, heavy-tailed noise", share_of(healthy.get("heavy_tailed_noise")), ""],
        ["the same heads, another noise draw: same verdict", share_of(pop.get("stability")), ""],
        [
            "one catalog effect: found",
            share_of(get(pop, "catalog_effect", "found")),
            joined([f"{k} {v}" for k, v in (get(pop, "catalog_effect", "verdicts") or {}).items()]),
        ],
        [
            "one catalog effect: found at its true setting",
            share_of(get(pop, "catalog_effect", "found_at_the_true_setting")),
            not_excluded_text(get(pop, "catalog_effect", "settings_not_excluded_per_find")),
        ],
        ["one catalog effect: parameters with the truth within U", share_of(get(pop, "catalog_effect", "truth_within_u")), ""],
        [
            "one catalog effect: every parameter within U at once",
            share_of(get(pop, "catalog_effect", "truth_within_u_every_parameter")),
            "",
        ],
        [
            "outside the catalog: called missing",
            share_of(get(pop, "outside_catalog", "missing")),
            joined([f"{k} {v}" for k, v in (get(pop, "outside_catalog", "verdicts") or {}).items()]),
        ],
        [
            "outside the catalog: signature's first variable of the right joint",
            share_of(get(pop, "outside_catalog", "signature_right_first")),
            "",
        ],
        [
            "outside the catalog: signature's first variable exactly",
            share_of(get(pop, "outside_catalog", "signature_exact_variable_first")),
            "",
        ],
        [
            "outside the catalog: signature's first entry a bump at the defect",
            share_of(get(pop, "outside_catalog", "signature_located")),
            "",
        ],
    ]
    seconds = pop.get("seconds_per_diagnosis") or {}
    tail = (
        f"\nSeconds per diagnosis ({seconds.get('what', '')}): median {num(seconds.get('median'), 's')}, max "
        f"{num(seconds.get('max'), 's')}. Claims on healthy heads: {joined([f'{k} {v}' for k, v in (healthy.get('claims') or {}).items()]) or 'none'}. "
        f"Measured on code {pop.get('code_sha256')}, commit {pop.get('commit', '-')} ({pop.get('mode')} run, {num(pop.get('run_seconds'), 's')}).\n"
    )
    speed = results.get("verdict_speed") or {}
    if speed:
        command, click = speed.get("command") or {}, speed.get("explorer_click") or {}
        clicked = (
            f"The explorer (a fresh `serve` on the shipped data, chromium, the page settled first) showed the verdict "
            f"{joined([num(x, 's') for x in click.get('seconds') or []])} after the click on Diagnose (target {num(click.get('target_s'), 's')} "
            f"each). "
            if click.get("seconds")
            else f"The explorer's click: {click.get('skipped', 'not measured')}. "
        )
        tail += (
            f"\nOne diagnosis of {speed.get('campaign')}, nothing else running, {num(speed.get('repeats'))} runs: the command "
            f"`diagnose` prints its verdict {num(get(command, 'verdict_s', 'median'), 's')} after launch (median, imports included; "
            f"max {num(get(command, 'verdict_s', 'max'), 's')}) and the nested figures {num(get(command, 'nested_s', 'median'), 's')} "
            f"after it (median); in one process the verdict takes {num(get(speed, 'in_process', 'verdict_s', 'median'), 's')}, the "
            f"{num(get(speed, 'in_process', 'without_nested_s'), 's')} without testing its claims on rings left out of the choice. {clicked}Targets: verdict median "
            f"{num(get(speed, 'targets', 'verdict_median_s'), 's')} and max {num(get(speed, 'targets', 'verdict_max_s'), 's')}, "
            f"nested {num(get(speed, 'targets', 'nested_s'), 's')}: {holds(speed.get('holds'))}. A fixed workload of the same "
            f"kind (`machine_reference_s`) took {num(get(speed, 'machine_reference_s', 'before'), 's')} before these runs and "
            f"{num(get(speed, 'machine_reference_s', 'after'), 's')} after: on this machine the same code's verdict moves by about a "
            f"second between hours, and every run is listed in "
            f"[the diagnosis's changes](methods/diagnosis_changes.md#faster-to-the-verdict-judged-alike).\n"
        )
        shape = speed.get("shape_campaign") or {}
        if shape.get("command_verdict_s"):
            tail += (
                f"\nA campaign with a shape no catalog holds ({shape.get('campaign')}; verdict `{shape.get('verdict')}`): the command "
                f"prints its verdict {num(get(shape, 'command_verdict_s', 'median'), 's')} after launch (median; max "
                f"{num(get(shape, 'command_verdict_s', 'max'), 's')}), the verdict waiting for the shapes it rests on, not for the "
                f"signature of what is left and the error history, which follow it; in one process "
                f"the search takes {num(get(shape, 'in_process_s', 'search'), 's')}, the signature of what is left "
                f"{num(get(shape, 'in_process_s', 'signature'), 's')}, the shapes {num(get(shape, 'in_process_s', 'shapes'), 's')} "
                f"(in a thread of their own from the moment the search stalls, beside its pair search: the two overlap), "
                f"the whole {num(get(shape, 'in_process_s', 'total'), 's')}. Target (issue 56): the verdict at most "
                f"{num(get(speed, 'targets', 'verdict_median_s'), 's')} (median): {holds(shape.get('holds'))}.\n"
            )
    tolerance = pop.get("tolerance") or {}
    if tolerance:
        tail += (
            f"\nThe within-noise test's tolerance (a ring's mean may hold this many times its noise variance of systematic "
            f"error), chosen over {num(get(tolerance, 'baseline_fails', str(tolerance.get('used')), 'of'))} other healthy heads "
            f"(seeds {joined([str(x) for x in tolerance.get('seeds') or []])}): the baseline fails on "
            + joined([f"{share_of(x)} at {k}" for k, x in (tolerance.get("baseline_fails") or {}).items()])
            + f"; used: {num(tolerance.get('used'))}.\n"
        )
    u_cal = pop.get("u_calibration") or {}
    if u_cal:
        tail += (
            f"\nThe jackknife's U over {num(get(u_cal, 'within_u', 'of'))} parameters of "
            f"{num(u_cal.get('heads_with_the_effect_found_exactly'))} calibration heads with one catalog effect found "
            f"(seeds {joined([str(x) for x in u_cal.get('seeds') or []])}, never the heads above): within U "
            f"{share_of(u_cal.get('within_u'))}; the 95th percentile of |fit - truth| / U {num(u_cal.get('q95_error_over_u'))}; "
            f"inflation used {num(u_cal.get('inflation_used'))}, measured {num(u_cal.get('inflation_measured'))}.\n"
        )
    by_effect = get(pop, "catalog_effect", "by_effect") or {}
    effects = table(["hidden catalog effect", "found"], [[k, share_of(v)] for k, v in by_effect.items()])
    return POPULATION_INTRO + "\n" + table(["heads", "figure (95 % interval)", "verdicts"], rows) + tail + "\n" + effects + "\n"


VERDICT_RATES_MARKER = "<!-- verdict-rates -->"


def verdict_rates(results: Mapping[str, Any]) -> str:
    """The population's verdicts by kind of head, and each verdict's own figure, for the diagnosis
    page (in place of VERDICT_RATES_MARKER): the figures beside the promises, never copied by hand."""
    pop = results.get("population") or {}
    if not pop:
        return "*No population run in benchmarks/results.json yet.*\n"
    unknown = results.get("population_unknown") or {}
    groups = {"healthy": "healthy heads", "catalog_effect": "one catalog effect hidden", "outside_catalog": "one effect in no catalog"}
    counts = {g: get(pop, g, "verdicts") or {} for g in groups}
    if unknown:
        groups |= {"unknown_shape": "one shape no catalog holds (families)", "multi_effect": "two or three catalog effects"}
        counts |= {"unknown_shape": get(unknown, "all", "verdicts") or {}, "multi_effect": get(unknown, "multi_effect", "verdicts") or {}}
    totals = {g: sum(counts[g].values()) for g in groups}

    def cell(group: str, verdict: str) -> str:
        k, n = counts[group].get(verdict, 0), totals[group]
        return f"{k} of {n} ({pct(k / n if n else None)})"

    every = get(unknown, "all") or {}
    own = {
        "none": f"false alarms on healthy heads {share_of(get(pop, 'healthy', 'false_alarm'))}; same verdict on another noise draw {share_of(pop.get('stability'))}; "
        f"a ring named as measured badly on healthy heads {share_of(get(pop, 'healthy', 'suspect_named'))}, touch outliers named "
        f"{share_of(get(pop, 'healthy', 'outliers_named'))}"
        + (
            f"; on heads with a shape no catalog holds, `none` {share_of(every.get('none'))}, of which with nothing named (no ring to "
            f"remeasure, no touch outliers) {share_of(every.get('none_silent'))}; a badly measured ring named {share_of(unknown.get('bad_ring_named'))}"
            if unknown
            else ""
        ),
        "missing": f"the hidden catalog effect found {share_of(get(pop, 'catalog_effect', 'found'))}; its parameters within U "
        f"{share_of(get(pop, 'catalog_effect', 'truth_within_u'))}; an effect in no catalog called missing {share_of(get(pop, 'outside_catalog', 'missing'))}"
        + (
            f"; a catalog effect named for a shape no catalog holds {share_of(every.get('catalog_name'))}; every effect of a head "
            f"with two or three claimed {share_of(get(unknown, 'multi_effect', 'all_found'))}"
            if unknown
            else ""
        ),
        "suggested": "no claim; `design --decide` proposes the rings that would confirm or refute it",
        "partial": "its found effect counts as found in the row above; what is left is read in the signature",
        "unexplained": f"the signature's first variable of the right joint {share_of(get(pop, 'outside_catalog', 'signature_right_first'))}; "
        "also the verdict when every suggestion's form breaks over the head",
        "uncatalogued": f"a shape claimed on healthy heads {share_of(get(pop, 'healthy', 'shape_claimed'))}, in place of a hidden "
        f"catalog effect {share_of(get(pop, 'catalog_effect', 'shape_in_place'))}"
        + (
            f"; on heads with a shape no catalog holds, the shape on its group {share_of(every.get('shape_right'))}, a wrong one "
            f"{share_of(every.get('shape_wrong'))}"
            if unknown
            else ""
        ),
    }
    verdicts = ("none", "missing", "suggested", "partial", "unexplained", "uncatalogued")
    rows = [[f"`{v}`", *(cell(g, v) for g in groups), own[v]] for v in verdicts]
    note = (
        f"\nMeasured by the benchmark [population](benchmarks.md#population) on commit {pop.get('commit') or pop.get('code_sha256')} "
        f"({pop.get('mode')} run)"
        + (
            f", and its part with shapes no catalog holds on commit {unknown.get('commit') or unknown.get('code_sha256')}"
            if unknown
            else ""
        )
        + "; intervals are 95 % Clopper-Pearson.\n"
    )
    return table(["verdict", *groups.values(), "its own figure"], rows) + note
