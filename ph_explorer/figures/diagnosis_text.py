"""A diagnosis in words: the one renderer of the record (diagnosis.results.Diagnosis) that the
command line, the HTML report and the explorer show.

`report_sections` gives the report as sections in reading order: the verdict and what to do next,
each claim with U and its untold partner, the suggestions, the worst rings with the test that
flagged each, the error history with its honest after; `detail="full"` adds everything else
(the tests' figures, every candidate and its partners, the teaching text). Each front end lays
the sections out; none decides anything from their words. Method: docs/diagnosis.md.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

from ph_explorer.campaign import orientation_label
from ph_explorer.diagnosis.candidates import Candidate, PairTest, Partner, UntoldShape
from ph_explorer.diagnosis.nested import MIN_TRAIN_PER_FOLD, NESTED_FOLDS
from ph_explorer.diagnosis.results import VERDICTS, Diagnosis, Headline
from ph_explorer.effects import Catalog, effect_label, settings_label, settings_text
from ph_explorer.effects.error_functions import SHAPE_GROUPS
from ph_explorer.figures.decision_text import undecided_text
from ph_explorer.figures.front_actions import Front, front_actions
from ph_explorer.figures.history_text import history_lines
from ph_explorer.figures.noise_text import base_text, campaign_test_line, test_lines
from ph_explorer.figures.ring_text import outliers_text, suspect_text, unvouched_check_text, worst_ring_lines
from ph_explorer.figures.shape_text import hours_text, pin_text, shape_lines, shape_name
from ph_explorer.planning.deciding import Decision

Detail = Literal["short", "full"]
SectionKey = Literal[
    "verdict", "why", "claims", "shapes", "suggested", "worst_rings", "history", "tests", "candidates", "partners", "teaching"
]
WORST_SHOWN = 5  # the worst rings named in the short report
SUGGESTED_SHOWN = 3  # the suggestions listed in the short report
RERANKED_SHOWN = 5  # rows of each table re-ranked after a step (full detail)


@dataclass(frozen=True)
class Section:
    """One part of the report: its key (what it is, for a front end's layout), a title, its lines."""

    key: SectionKey
    title: str
    lines: tuple[str, ...]


def unfolded_lines(result: Diagnosis) -> list[str]:
    """Why the claims were not tested on rings left out of the choice, when too few training rings
    make no folds (diagnosis.nested): they rest on the search's own test."""
    train = int((~result.held_out).sum())
    if not result.found or result.nested is not None or train >= MIN_TRAIN_PER_FOLD * NESTED_FOLDS:
        return []
    return [
        f"These claims rest on the search's own test: {train} training rings make no {NESTED_FOLDS} folds of "
        f"{MIN_TRAIN_PER_FOLD} to leave out of the choice, so their gain on rings left out of it is not tested."
    ]


def report_sections(
    result: Diagnosis,
    catalog: Catalog,
    detail: Detail = "short",
    name: Callable[[str], str] = str,
    front: Front = "command line",
    decision: Decision | None = None,
    data_file: str | None = None,
) -> list[Section]:
    """The report in reading order (module docstring); `name` writes text naming effects (a
    teaching report's letters, figures.diagnosis_report.EffectNames.text); `front`: whose actions
    the next step names (the explorer shows a claim's fit in its own table, not in a line);
    `decision`: the rings that would decide what the verdict leaves open, when found (next_step);
    `data_file`: the campaign's file, which the commands then name."""
    actions = front_actions(front, data_file)
    # With the decision found, a claim's line points to the next step, which says what rings can decide.
    told = actions if decision is None else {**actions, "decide": "see the next step"}
    claims = tuple(line for c in result.found for line in claim_lines(c, catalog, told, with_fit=front != "explorer"))
    claims += tuple(unfolded_lines(result))
    sections = [
        Section(
            "verdict",
            verdict_headline(result.headline, catalog, front == "explorer", result.tested),
            tuple(verdict_lines(result, actions, decision)),
        ),
        Section("why", "Why", tuple(why_lines(result))),
        Section("claims", "Found", claims),
        Section("shapes", "Shapes no catalog holds", tuple(line for shape in result.shapes for line in shape_lines(shape))),
        Section(
            "suggested", "Suggested, not claimed", tuple(suggestion_lines(result, catalog, SUGGESTED_SHOWN if detail == "short" else None))
        ),
        Section("worst_rings", "Where it fails", tuple(worst_ring_lines(result, WORST_SHOWN if detail == "short" else None))),
        Section(
            "history", "Error history on the check rings (MAE / um, and the noise floor)", tuple(history_lines(result.steps, result.nested))
        ),
    ]
    if detail == "full":  # before the history, which stays last (the honest after ends the report)
        sections[2:2] = [Section("tests", "The tests", tuple(test_lines(result, catalog)))]
        sections[-1:-1] = [
            Section("candidates", "Candidate effects, best first", tuple(candidate_table(result, catalog))),
            Section("partners", "What the campaign cannot tell apart", tuple(partner_lines(result, actions, catalog))),
            Section("teaching", "The effect found", (result.found[0].teaching,) if result.found else ()),
        ]
    return [Section(s.key, name(s.title), tuple(name(line) for line in s.lines)) for s in sections if s.lines or s.key == "verdict"]


def report_text(
    result: Diagnosis,
    catalog: Catalog,
    detail: Detail = "short",
    decision: Decision | None = None,
    headline: bool = True,
    data_file: str | None = None,
) -> str:
    """The report as plain text: each section's title, its lines indented; without the headline if said already."""
    sections = report_sections(result, catalog, detail, decision=decision, data_file=data_file)
    blocks = ["\n".join([s.title, *(f"  {line}" for line in s.lines)]) for s in sections]
    return "\n\n".join([blocks[0] if headline else blocks[0].partition("\n")[2], *blocks[1:]]) + "\n"


# -- the verdict -------------------------------------------------------------------------------------


# A verdict's promise when nothing could be tested against noise (Diagnosis.tested: one repetition).
UNTESTED = "one repetition per ring, so no repetition spread: nothing here is tested against noise"


def verdict_headline(headline: Headline, catalog: Catalog, pairs_only: bool = False, tested: bool = True) -> str:
    """'Verdict: missing - b_axis_cyclic 22 cycles/rev: catalog effects found, ...'; a claim the rings
    cannot tell from a partner is named with it, as a pair (issue 55: the credit is the pair's).
    pairs_only: only the claims named as pairs (the explorer names each claim beside its checkbox).
    tested: False when the rings could not be tested against noise; then no verdict's promise holds."""
    worded: set[str] = set()  # the shape groups already named in words: a later mention says "the same shape"
    named = "; ".join(
        [claim_name(c, headline, catalog, worded) for c in headline.found if c.untold or c.untold_shape or not pairs_only]
        + [shape_name(shape) for shape in headline.claimed_shapes]
    )
    return f"Verdict: {headline.verdict} - " + (f"{named}: " if named else "") + f"{VERDICTS[headline.verdict] if tested else UNTESTED}."


def claim_name(candidate: Candidate, headline: Headline, catalog: Catalog, worded: set[str] | None = None) -> str:
    """A claim by its effect and setting, or with the partners these rings cannot tell it from; a
    shape partner is named in words once per line (`worded`: the groups named so far), then "the same shape"."""
    ranked = {c.effect: c.settings for c in headline.candidates}  # a record without a partner's settings: its ranking's
    name = named_at(candidate.effect, [candidate.settings], catalog)
    partners = [named_at(p.effect, p.settings or [ranked.get(p.effect, {})], catalog) for p in candidate.untold]
    worded = set() if worded is None else worded
    if (shape := candidate.untold_shape) is not None:
        partners.append("the same shape" if shape.group in worded else f"a shape: {shape.words}")
        worded.add(shape.group)
    return f"{name} or {' or '.join(partners)} (these rings cannot tell)" if partners else name


def named_at(effect: str, settings: Sequence[dict], catalog: Catalog | None) -> str:
    """An effect at one or several settings ('a_axis_tilt_motion 19-21 cycles/rev'); its id alone without them or the catalog."""
    return settings_label(catalog[effect](), list(settings)) if catalog is not None and effect in catalog and settings else effect


def verdict_lines(result: Diagnosis, actions: dict[str, str], decision: Decision | None = None) -> list[str]:
    """Under the headline: the rings to remeasure, a resumed study, and what to do next."""
    lines = [suspect_text(ring) for ring in result.suspect_rings]
    if result.touch_outliers is not None and result.touch_outliers.named:
        lines.append(outliers_text(result.touch_outliers))
    if result.base or result.base_unused:
        lines.append(base_text(result))
    if result.started_from > len(result.base):
        already = ", ".join(effect_label(e) for e in result.chain[len(result.base) : result.started_from])
        lines.append(f"Resumed with {already} in the model; the search continued from there.")
    remeasure = ""
    if result.suspect_rings:
        named = ", ".join(orientation_label(r.a_deg, r.b_deg) for r in result.suspect_rings)
        remeasure = f"remeasure {named} and diagnose again; of the other rings: "
    return lines + ["Next: " + remeasure + next_step(result, actions, decision)]


def why_lines(result: Diagnosis) -> list[str]:
    """Why the verdict: the campaign's within-noise test in one line; for a failure no claim explains,
    what is left in the head's variables and how many catalog fits were implausible."""
    lines = [campaign_test_line(result)]
    if result.verdict in ("partial", "unexplained", "uncatalogued"):
        lines.append(left_line(result))
    implausible = [c for c in result.candidates if c.status == "implausible"]
    if result.verdict == "unexplained" and implausible:
        lines.append(
            f"{len(implausible)} catalog effects would explain more than noise only with implausible parameters "
            "(--detail full lists them): none is the explanation."
        )
    return lines


def breakable(effect_id: str) -> str:
    """An effect's id in HTML that a narrow column breaks after an underscore, not inside a word."""
    return effect_id.replace("_", "_<wbr>")


def next_step(result: Diagnosis, actions: dict[str, str], decision: Decision | None = None) -> str:
    """What to do next, by verdict and by what the diagnosis leaves open, with the front end's actions;
    with the decision found, what rings can decide and what they cannot (no button says no ring does)."""
    if not result.tested:
        return "measure each ring again (two repetitions or more; the paper's campaign has 10) and diagnose again: one shows no noise to judge by."
    # A claimed shape's band narrows where its variable's band is widest, whatever else is open.
    pins = "; ".join(f"to pin {shape.id} down, {pin_text(shape)}" for shape in result.claimed_shapes)
    if result.leaves_open:
        what = "confirm the suggestion" if result.open_suggestions and not result.found else "decide what these rings cannot tell"
        if decision is None:
            return f"measure the rings that would {what} ({actions['decide']})." + (f" Then, {pins}." if pins else "")
        undecided = undecided_text(decision)
        rest = "the rest" if undecided else "what these rings leave open"
        measure = f"measure the {len(decision.rings)} rings that would decide {rest} ({actions['decide']})." if decision.rings else ""
        text = f"{undecided} {measure[:1].upper()}{measure[1:]}".strip() if undecided else measure
        return f"{text} {pins[:1].upper()}{pins[1:]}.".strip() if pins else text
    if result.verdict == "none" and (unvouched := unvouched_check_text(result, actions["next"])):
        return unvouched
    closest = closest_shape_text(result)
    look = "look at what is left in the head's variables; "
    return {
        "none": "nothing is missing that this campaign shows; a model of it is within noise.",
        "missing": actions["add"] + ".",
        "suggested": f"measure more rings where the suggestion predicts the largest difference ({actions['decide']}).",
        "partial": f"add the effects found, then look at what is left: {closest}an effect outside the catalog ({actions['own']}) may explain it.",
        "unexplained": f"no catalog effect explains the failure: {closest or look}else {own_effect_text(actions)}.",
        "uncatalogued": f"the shape found is added in the error history below ({actions['keep']}); {pins}.",
    }[result.verdict]


def closest_shape_text(result: Diagnosis) -> str:
    """The shape that came closest and was not claimed, with the rings that would pin it down (they
    come before an effect file of the user's own: what neither the catalog nor a shape holds)."""
    tried = next((shape for shape in result.shapes if not shape.claimed), None)
    return f"the closest shape, {tried.id}, is not claimed: to pin it down, {pin_text(tried)}; " if tried is not None else ""


def own_effect_text(actions: dict[str, str]) -> str:
    """The last resort for what neither the catalog nor a shape holds: an effect of the user's own."""
    return f"write the effect that has that signature ({actions['own']})"


def left_next(result: Diagnosis, front: Front = "command line") -> str:
    """What to do with what is left (the signature), one sentence: the shape claimed for it added, else
    the closest shape pinned down, else an effect of the user's own; never only the last while a
    shape was tried."""
    actions = front_actions(front)
    if result.claimed_shapes:
        shapes = " and ".join(f"{shape.id} ({shape_name(shape)})" for shape in result.claimed_shapes)
        return f"What the rings replicate of it is claimed as a shape, {shapes}: {actions['add']}."
    own = f"{own_effect_text(actions)} and diagnose again with it."
    closest = closest_shape_text(result)
    return f"{closest[:1].upper()}{closest[1:]}else {own}" if closest else own[:1].upper() + own[1:]


def left_line(result: Diagnosis) -> str:
    significant = [entry for entry in result.signature if entry["significant"]]
    what = "; ".join(signature_text(entry) for entry in significant[:5]) if significant else "nothing beyond noise in any single variable"
    return f"What is left, in the head's own variables (share of the residual explained; noise alone): {what}."


# -- claims, suggestions, partners -------------------------------------------------------------------


def claim_lines(candidate: Candidate, catalog: Catalog, actions: dict[str, str], with_fit: bool = True) -> list[str]:
    """A claim with its parameters +- U (k = 2), then at most three lines: the shape whose look
    carried it, the partners these rings cannot tell it from, in one voice, and the settings they
    cannot exclude."""
    effect = catalog[candidate.effect]().with_settings(**candidate.settings)
    fit = " (its fit: the table below)"
    if with_fit:
        fit = f": {catalog[candidate.effect].parameters_text(candidate.params, candidate.params_u)} (+- U, k = 2)"
    told = [p for p in candidate.confounded_with if p.told_apart]
    lines = (
        [f"{effect_label(effect)}{fit}."]
        if with_fit or candidate.untold or told or candidate.rival_setting or candidate.untold_shape
        else []
    )
    if candidate.on_shape:
        lines.append(f"  {candidate.note[0].upper()}{candidate.note[1:]}.")
    partners = [untold_text(candidate.effect, candidate.untold, actions, catalog)] if candidate.untold else []
    partners += [told_text(candidate.effect, p, catalog) for p in told]
    if candidate.untold_shape is not None:
        partners.append(untold_shape_text(candidate.untold_shape))
    if partners:
        lines.append("  " + " ".join(partners))
    settings = []
    if candidate.settings_not_excluded and with_fit:
        settings.append(
            f"the campaign cannot exclude {settings_text(effect, list(candidate.settings_not_excluded))} beside this setting (95 %)"
        )
    if (rival := candidate.rival_setting) is not None:
        settings.append(
            f"the rings cannot tell it from {settings_text(effect, [rival.settings])} ({test_text(rival.test)}); the rings that would: {actions['decide']}"
        )
    if settings:
        lines.append("  " + "; ".join(settings) + ".")
    return lines


def untold_shape_text(shape: UntoldShape) -> str:
    """The shape of another variable the rings cannot tell a claim from, and what would."""
    decide = (
        "lattice rings measured again after the check rings would tell a change in time from the head"
        if SHAPE_GROUPS[shape.group].variable == "time"
        else "rings off the lattice where the two predict most differently would tell them apart"
    )
    return f"Or a shape no catalog holds, {shape.words}: the rings cannot tell it from this claim (the claim {test_text(shape.test)}); {decide}."


def untold_text(effect: str, partners: Sequence[Partner], actions: dict[str, str], catalog: Catalog | None = None) -> str:
    """One voice on the partners the rings cannot tell a claim from (at their settings, given the
    catalog): how much each shares, the rings' test, and what would decide."""
    shared = "; ".join(
        f"{named_at(partner.effect, partner.settings, catalog)}, which explains {percent(partner.shared)} of what this campaign shows of {effect}"
        + (f" (the rings' test: {test_text(partner.test)})" if partner.test is not None else "")
        for partner in partners
    )
    measurements = sorted({p.separated_by.measurement for p in partners if p.separated_by is not None and p.separated_by.measurement})
    if measurements:
        decide = f"measuring {' or '.join(measurements)} would separate them"
    else:
        decide = f"no measurement tried (rings near A0 = 0, off-grid rings, a reversed scan, a longer stylus) lowers what they share; whether more rings would decide, and with what power: {actions['decide']}"
    return f"or {shared}: these rings cannot tell them apart; {decide}."


def suggestion_lines(result: Diagnosis, catalog: Catalog, limit: int | None) -> list[str]:
    """Each suggestion with its parameters and why it is not claimed (the first `limit`, all when None)."""
    confirm = "More rings where it predicts the largest difference would confirm or refute it."
    own = "No catalog effect has this form: the head's error has a shape of its own (see what is left in its own variables)."
    lines = [
        f"{c.effect} ({catalog[c.effect].parameters_text(c.params, c.params_u)}); {c.note}. {own if c.form_broken else confirm}"
        for c in result.suggested[:limit]
    ]
    more = len(result.suggested) - len(lines)
    return lines + ([f"... and {more} more (--detail full)."] if more else [])


def partner_lines(result: Diagnosis, actions: dict[str, str], catalog: Catalog | None = None) -> list[str]:
    """Every candidate's confounded partners (full detail): the claims' and those beyond noise."""
    lines = []
    for candidate in result.found or [c for c in result.candidates if c.beyond_noise]:
        for partner in candidate.confounded_with:
            if partner.told_apart:
                lines.append(told_text(candidate.effect, partner, catalog))
            elif partner.told_apart is False:
                lines.append(f"{candidate.effect} {untold_text(candidate.effect, [partner], actions, catalog)}")
            else:
                lines.append(
                    f"{shared_text(candidate.effect, partner, catalog)}: this campaign cannot tell them apart; the credit is not theirs to split."
                )
    return lines


def shared_text(effect: str, partner: Partner, catalog: Catalog | None = None) -> str:
    """'93 % of what this campaign shows of X is also explained by Y' (the largest squared canonical
    correlation of their columns over the touches; Y at its settings, given the catalog)."""
    return f"{percent(partner.shared)} of what this campaign shows of {effect} is also explained by {named_at(partner.effect, partner.settings, catalog)}"


def told_text(effect: str, partner: Partner, catalog: Catalog | None = None) -> str:
    """A partner the rings tell the effect from: what they share, and the rings' test."""
    return f"{shared_text(effect, partner, catalog)}, yet the rings tell them apart: {test_text(partner.test)}."


def test_text(test: PairTest) -> str:
    """'better on 10 of the 12 rings where their predictions differ, p = 0.002 (...)': diagnosis.telling_apart in words."""
    if test.rings == 0:
        return "their predictions differ on no ring"
    where = f"of the {test.rings} rings where their predictions differ"
    return f"better on {test.rings_better} {where}, p = {test.p_value:.3g} ({test.p_without_top:.3g} without the top ring)"


def percent(share: float) -> str:
    """'83 %', '99.6 %': a share near 1 keeps a decimal (rounded to 100 % it would read as identical)."""
    return f"{100 * share:.1f} %" if 0.995 <= share < 1.0 else f"{100 * share:.0f} %"


def signature_text(entry: dict) -> str:
    """'b_joint_deg periodic, 22 cycles/rev, 8.4 % (0.07 %)': one entry of a signature in words (a time in hours)."""
    setting = {
        "cycles_per_rev": "{:g} cycles/rev".format,
        "cycles_per_span": "{:g} cycles over its span".format,
        "centre_deg": lambda deg: f"at {round(deg, 1):g} deg",  # to a tenth of a degree, not a float's digits
        "centre_s": lambda s: f"at {hours_text(s)}",
        "centre_touch": "at touch {:g}".format,
        "joint": "{} joint".format,
    }
    where = ", ".join(text(entry[key]) for key, text in setting.items() if key in entry)
    return (
        f"{entry['variable']} {entry['kind']}, {where}, {100 * entry['explained_fraction']:.1f} % ({100 * entry['noise_fraction']:.2f} %)"
    )


# -- candidates ------------------------------------------------------------------------------------


def candidate_table(result: Diagnosis, catalog: Catalog) -> list[str]:
    """The ranked candidates (full detail), then each re-ranking after a step."""
    lines = ["share of the out-of-sample residual explained, fall of the held-out error; * significant"]
    lines += ranking_lines(result.candidates, catalog)
    chain: list[str] = []
    for found, ranking in zip(result.found, result.reranked):
        chain.append(effect_label(catalog[found.effect]().with_settings(**found.settings)))
        lines += [f"Re-ranked with {' + '.join(chain)} in the model (top {RERANKED_SHOWN}):"]
        lines += ranking_lines(ranking[:RERANKED_SHOWN], catalog)
    return lines


def ranking_lines(candidates: Sequence[Candidate], catalog: Catalog) -> list[str]:
    lines = []
    width = max([len(c.effect) for c in candidates] + [6])
    for c in candidates:
        if c.status == "not tested":
            lines.append(f"  {c.effect.ljust(width)}  not tested: {c.note}")
            continue
        shown = c.significant or c.beyond_noise  # a fit of noise describes nothing
        params = catalog[c.effect].parameters_text(c.params, c.params_u) if shown else ""
        lines.append(
            f"{'*' if c.significant else ' '} {c.effect.ljust(width)}  explains {100 * c.explained_fraction:5.1f} %  "
            f"(noise alone {100 * c.noise_fraction:5.2f} %)  error -{100 * c.error_reduction:4.1f} %  {c.status}"
            + (f": {params}" if params else "")
            + (f"  ({c.note})" if c.note and c.status != "not significant" else "")
        )
    return lines
