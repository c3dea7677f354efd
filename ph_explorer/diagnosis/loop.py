"""The loop: see where a model fails, find the missing physical effect, add it, watch the error fall.

1. Where it fails: the out-of-sample error at every orientation, each against its own noise floor.
2. Which effect is missing: ph_explorer.diagnosis.search.
3. Add it: a HybridModel with the chosen effects + the data-driven part.
4. Watch the error fall: the check-ring MAE of each step against both references and the floors.

The verdict (VERDICTS) comes from the within-noise test (ph_explorer.diagnosis.within_noise).
Method: docs/methods/diagnosis_loop.md.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor, wait as all_done
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from ph_explorer import metrics
from ph_explorer.blas import one_blas_thread, stand_in_for_main
from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.candidates import Candidate
from ph_explorer.diagnosis.catalog_behind import held_by_catalog
from ph_explorer.diagnosis.choice import Choice, choose_effects
from ph_explorer.diagnosis.nested import held_out_claims
from ph_explorer.diagnosis.partners import confounding
from ph_explorer.diagnosis.results import ChainLink, Diagnosis, Headline, Ring, Step, Verdict, flagged_in
from ph_explorer.diagnosis.search import CandidateSearch
from ph_explorer.diagnosis.shapes import Shape, find_shapes
from ph_explorer.diagnosis.signature import signature
from ph_explorer.diagnosis.suspect import suspect_rings, without_suspects
from ph_explorer.diagnosis.telling_apart import tell_apart
from ph_explorer.diagnosis.touch_outliers import at_repetition_median, touch_outliers
from ph_explorer.diagnosis.within_noise import NoiseTest
from ph_explorer.effects import DEFAULT_CATALOG, Catalog, Effect
from ph_explorer.errors import InputError
from ph_explorer.kinematics import campaign_touches
from ph_explorer.models.crossval import held_out_mae, held_out_ring_mae
from ph_explorer.models.deviation_model import DeviationModel
from ph_explorer.models.hybrid import DataPart, HybridModel


def repetition_sigma(campaign: Campaign, model: HybridModel | None = None) -> float:
    """Pooled repetition sigma per touch (um) of what the model's physical terms leave.

    Terms that change between repetitions (direction with an alternating scan, drift) inflate the
    raw repetition spread; once they are modelled, the noise floor is read from what remains.
    """
    if model is None or not model.effects:
        return campaign.noise_sigma_um()
    return metrics.pooled_sigma(campaign.deviations - model.physical_part(campaign_touches(campaign)))


def out_of_sample_figures(
    search: CandidateSearch, campaign: Campaign, baseline: DeviationModel | None, held_out: NDArray[np.bool_]
) -> tuple[dict[str, NDArray[np.float64]], dict[str, NDArray[np.float64]]]:
    """Each ring's out-of-sample MAE and its own floor, against the mean and single repetitions.

    baseline: a model of another kind than the trilinear interpolator, which then speaks for
    itself at the check rings; None when the baseline is the interpolator itself.
    """
    sigma, n_rep = campaign.noise_sigma_um(), campaign.n_repetitions
    mae = metrics.ring_mae(campaign.deviations - search.residual, campaign.deviations)
    floors = search.smoother.noise_floor(sigma, n_rep, campaign.noise_law())
    if baseline is not None:
        own = held_out_ring_mae(baseline, campaign, held_out)
        floor = campaign.noise_floor_um()
        for reference in metrics.REFERENCES:
            mae[reference][held_out] = own[reference]
            floors[reference][held_out] = floor[reference]
    return mae, floors


def settle_presence(candidates: Sequence[Candidate], final: Sequence[Candidate], found: Sequence[str]) -> list[Candidate]:
    """The candidates, judged again in the last ranking (with the effects found in the model): one
    beyond noise in the first ranking only because it took a share of what an effect found
    explains is not "present"."""
    last = {c.effect: c for c in final}
    out = []
    for candidate in candidates:
        if candidate.beyond_noise and not candidate.significant and not getattr(last.get(candidate.effect), "beyond_noise", False):
            candidate = replace(
                candidate, beyond_noise=False, note=candidate.note or f"beyond noise only with {', '.join(found)} left out of the model"
            )
        out.append(candidate)
    return out


def decide(before: NoiseTest | None, after: NoiseTest | None, found: bool, suggested: bool = False) -> Verdict:
    """The verdict (see VERDICTS) from the within-noise tests before and after the effects found.

    Found effects are replicated over rings (diagnosis.replication); a baseline that fails with
    only unreplicated candidates is "suggested". A campaign of one repetition has no noise to
    test against: found effects are "missing", none found is "none", and the report says that
    "within noise" could not be tested.
    """
    if not found:
        fails = before is not None and before.fails
        return ("suggested" if suggested else "unexplained") if fails else "none"
    return "partial" if after is not None and after.fails else "missing"


UNEXPLAINED = ("partial", "unexplained", "suggested")  # verdicts whose remainder a shape may describe


class ShapesAhead:
    """The shapes looked for in a thread of their own from the moment one effect at a time stalls on
    a model that fails (choose_effects' on_stall), while the pair search and the nested folds run
    on: find_shapes's result, used when the verdict's chain and test are the ones it started from
    (nothing it reads changes), else looked for again. A look whose chain moves on (a pair taken)
    is dropped: the groups it has not begun are not fitted. Only from the main thread: elsewhere
    (a Dask task's) the other core is taken (blas.parts_at_once)."""

    # At the search's own priority: at the lowest (nice 19) the verdict, which waits for the look,
    # took 20 times as long on a machine busy with other programs (docs/methods/diagnosis_changes.md).
    _pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="ph-explorer-shapes", initializer=stand_in_for_main)

    def __init__(self, seed: int) -> None:
        self.seed = seed
        self.started: tuple[CandidateSearch, list[Effect], NoiseTest, threading.Event, Future[list[Shape]]] | None = None
        self.dropped: list[Future[list[Shape]]] = []

    def start(self, search: CandidateSearch, chain: list[Effect], current: NoiseTest) -> Callable[[], None]:
        """A look at the shapes beside this chain begun; returns what drops it."""
        if self.started is None and threading.current_thread() is threading.main_thread():
            stop = threading.Event()
            self.started = (search, chain, current, stop, self._pool.submit(find_shapes, search, chain, current, self.seed, stop=stop))
        return self.drop

    def drop(self) -> None:
        """The look no longer wanted: it stops before its next groups (it raises blas.Dropped)."""
        if self.started is not None:
            self.started[3].set()
            self.dropped.append(self.started[4])
            self.started = None

    def shapes(self, search: CandidateSearch, chain: Sequence[Effect], current: NoiseTest | None) -> list[Shape]:
        """find_shapes(search, chain, current): the one looked for ahead when it is the same."""
        if self.started is not None:
            was_search, was_chain, was_current, _, look = self.started
            same_chain = len(was_chain) == len(chain) and all(a is b for a, b in zip(was_chain, chain))
            if was_search is search and was_current is current and same_chain:
                return look.result()
        self.drop()
        return find_shapes(search, chain, current, self.seed)

    def wait(self) -> None:
        """Every look ended, used or not (they read the search's designs, about to be let go)."""
        self.drop()
        all_done(self.dropped)


def verdict_of(choice: Choice, based: int) -> Verdict:
    """The verdict of a choice (decide): found when the chain holds claims beyond the `based` base
    effects; a suggestion whose form breaks over the head is no catalog effect the rings could confirm."""
    open_suggestion = any(not c.form_broken for c in flagged_in(choice.rankings, "suggested"))
    return decide(choice.based, choice.after, bool(choice.chain[based:]), open_suggestion)


def add_effects(
    campaign: Campaign,
    effects: Sequence[Effect],
    data_part: DataPart = "trilinear",
    progress: Callable[[str, float], None] | None = None,
) -> tuple[HybridModel, Step]:
    """Fit the hybrid with these physical effects (each at its own settings) on the campaign and
    measure it on the held-out rings.

    Returns the fitted model and its Step (MAE against both references, and the noise floor of
    what its physical terms leave).
    """
    held_out = campaign.holdout_mask()
    hybrid = HybridModel(list(effects), data_part, progress=progress).fit(campaign, ~held_out)
    floor = metrics.noise_floor(repetition_sigma(campaign, hybrid), campaign.n_repetitions, law=campaign.noise_law())
    model = f"hybrid, {hybrid.data_part.name} data part" if effects else hybrid.data_part.name
    step = Step(tuple(e.id for e in effects), held_out_mae(hybrid, campaign, held_out), floor, tuple(hybrid.effect_parameters()), model)
    return hybrid, step


@one_blas_thread
def diagnose(
    campaign: Campaign,
    add: Sequence[str] | None = None,
    baseline: DeviationModel | None = None,
    data_part: DataPart = "trilinear",
    catalog: Catalog = DEFAULT_CATALOG,
    max_steps: int = 3,
    progress: Callable[[str], None] | None = None,
    seed: int = 0,
    nested: bool = True,
    start: Sequence[Effect] = (),
    on_verdict: Callable[[Headline], None] | None = None,
    base: Sequence[Effect] = (),
) -> Diagnosis:
    """Run the whole loop on a campaign; the check rings (campaign.holdout_mask()) are never fitted.

    add: effect ids to add in that order; None adds the best significant candidate, then searches
    again (at most max_steps effects). baseline: a trained model to start from (default: the
    trilinear model on the training rings). catalog: the effects to choose from. progress: told
    what the loop does ("scanning <effect>", ...). nested: a claim stands only when its gain holds
    on rings that took no part in choosing it (diagnosis.nested; False: untested so, for tests of
    other parts). start: effects already in the model at their settings (a resumed study's chain):
    the search continues from them. base: effects never claimed, those the rings can use in the
    model before the search (choice.usable_base; planning.adaptive's location errors): the verdict
    judges what lies beyond them. on_verdict: called with the verdict as soon as it stands.
    Method: docs/diagnosis.md.
    """
    # Touches read far off are named and read at their point's repetition median; rings measured
    # badly are named and left out of the fit and of the claims (result.judged).
    outliers = touch_outliers(campaign)
    campaign = at_repetition_median(campaign, outliers)
    suspects = suspect_rings(campaign, seed)
    campaign = without_suspects(campaign, suspects)
    held_out = campaign.holdout_mask()
    train = ~held_out
    if train.sum() < 4:
        raise InputError("too few training orientations to diagnose (need at least 4 off the held-out set)", file=campaign.source)
    if not held_out.any():
        raise InputError(
            "no held-out orientation to measure the error on: give check orientations in the sidecar or off-grid rings",
            file=campaign.source,
        )
    candidates_by_id = catalog.candidates()
    for effect_id in add or []:
        if effect_id not in catalog:
            raise catalog.unknown(effect_id, column=None)
        if effect_id not in catalog.addable():
            raise InputError(f"effect {effect_id!r} cannot be added to a model: {catalog[effect_id].name} is not systematic")
    effects = [cls() for cls in candidates_by_id.values()]
    by_id = {e.id: e for e in effects}

    if baseline is None:
        baseline = HybridModel([], data_part).fit(campaign, train)
        baseline_name = baseline.data_part.name
    else:
        baseline_name = baseline.name
    baseline_mae = held_out_mae(baseline, campaign, held_out)

    # 1 + 2. where it fails, and which effects are missing (the verdict's chain, whatever the user adds)
    ahead = ShapesAhead(seed)
    choice = choose_effects(campaign, train, effects, max_steps, seed, progress, start=start, base=base, on_stall=ahead.start)
    search, before = choice.search, choice.before
    offered, base = base, choice.base  # the base model's effects these rings can use (choice.usable_base)
    fixed = len(base) + len(start)  # the chain's effects in the model before the search
    # A claim's gain must survive the choice made inside the folds, on rings left out of it (check
    # rings included): else its effects are suggestions (diagnosis.nested).
    if nested and choice.chain[fixed:] and progress is not None:
        progress("testing the claims on rings left out of the choice (nested cross-validation)")
    choice, honest = held_out_claims(choice, campaign, fixed, seed) if nested else (choice, None)
    interpolator = search.smoother.model_name
    mae, floors = out_of_sample_figures(search, campaign, None if baseline_name == interpolator else baseline, held_out)
    verdict = verdict_of(choice, len(base))
    # A shape for what the catalog does not explain: an error function of the head's own variables
    # no catalog holds; catalog effects of its own kind that hold it are claimed in its place
    # (diagnosis.catalog_behind), and the shapes are looked for again beside them.
    if verdict in UNEXPLAINED and progress is not None:
        progress("looking for a shape of what the catalog leaves")
    shapes = ahead.shapes(search, choice.chain, choice.after if choice.chain else before) if verdict in UNEXPLAINED else []
    ahead.drop()  # a look not used is not waited for
    if any(shape.claimed for shape in shapes):
        held, shapes = held_by_catalog(choice, shapes, effects, seed)
        if held is not choice:
            choice, verdict = held, verdict_of(held, len(base))
            shapes = find_shapes(search, choice.chain, choice.after, seed) if verdict in UNEXPLAINED else []
    chain = choice.chain
    unexplained = verdict in UNEXPLAINED
    shape_effects = [shape.effect() for shape in shapes if shape.claimed]
    verdict = "uncatalogued" if shape_effects else verdict
    # No claim, no partners to name with it: the verdict is said before the rankings are told apart.
    if on_verdict is not None and not choice.found:
        on_verdict(Headline(verdict, (), tuple(choice.candidates), tuple(shapes)))
    # What the search learnt of its first ranking, each stage returning new candidates.
    candidates = choice.candidates
    if chain:
        candidates = settle_presence(candidates, choice.remaining, [c.effect for c in choice.found])
    # Each claim with the partners this campaign cannot tell it from and the settings the rings
    # cannot exclude, in the ranking it was taken from (ranking k has the chain's first k effects
    # beyond `start` in the model); the first ranking's every candidate with its partners.
    rankings, learnt = [], {}
    for k, ranking in enumerate([candidates, *choice.rankings[1:]]):
        taken = [c.effect for c in choice.found] if k == 0 else [c.effect for c in choice.found if any(c is r for r in ranking)]
        if k == 0 or taken or any(c is w for c in ranking for w in choice.withdrawn):
            told = tell_apart(search, confounding(search, ranking, by_id), taken, by_id, chain[: fixed + k], seed)
            learnt |= {id(old): new for old, new in zip(ranking, told)}
            ranking = told
        rankings.append(ranking)
    candidates = rankings[0]
    found = tuple(learnt.get(id(c), c) for c in choice.found)
    if on_verdict is not None and choice.found:
        on_verdict(Headline(verdict, found, tuple(candidates), tuple(shapes)))
    left = signature(search, fixed=search.design(chain) if chain else None) if unexplained else []

    # The base model's parameters +- U in the verdict's model (the search's chain, its claims in it).
    base_fit = [ChainLink(e.id, e.settings(), *fit) for e, fit in zip(base, search.fitted_u(chain, len(base)) if base else [])]
    ahead.wait()
    search.forget_designs()  # everything asked of them is answered; the history's fits need the memory

    # 3 + 4. add effects one at a time (the chain, or the user's), each step refitted and measured
    # on the check rings
    floor = campaign.noise_floor_um()
    steps = [Step((), baseline_mae, floor, model=baseline_name)]
    scan = {c.effect: c for c in candidates}
    if add is None:
        chosen_steps = chain
    else:
        # A shape of a shapes file is added at its knots (nothing is scanned): the catalog's class.
        chosen_steps = [
            *base,
            *start,
            *(by_id[i].with_settings(**(scan[i].settings if i in scan else {})) if i in by_id else catalog[i]() for i in add),
        ]
    hybrid = None
    for count in range(len(base) or 1, len(chosen_steps) + 1):  # the base model is one step
        hybrid, step = add_effects(campaign, chosen_steps[:count], data_part)
        steps.append(step)
    if add is None and shape_effects:  # the shapes claimed, added as one step
        hybrid, step = add_effects(campaign, [*chosen_steps, *shape_effects], data_part)
        steps.append(step)

    by_scatter = before.ring_by_scatter if before is not None else np.zeros(campaign.n_orientations, dtype=bool)
    rings = tuple(
        Ring(
            float(a),
            float(b),
            bool(held_out[i]),
            {k: float(v[i]) for k, v in mae.items()},
            {k: float(v[i]) for k, v in floors.items()},
            None if before is None else bool(before.ring_exceeds[i]),
            bool(by_scatter[i]),
        )
        for i, (a, b) in enumerate(campaign.orientations)
    )
    return Diagnosis(
        verdict=verdict,
        # The touch noise once the modelled effects that change between repetitions are taken out.
        noise_floor_um=steps[-1].noise_floor_um,
        baseline_model=baseline_name,
        baseline_mae_um=baseline_mae,
        candidates=tuple(candidates),
        found=found,
        # A claim the folds withdrew is suggested as the ranking it was taken from told it apart.
        suggested=flagged_in([[learnt[id(c)] for c in choice.withdrawn if id(c) in learnt], *rankings], "suggested"),
        not_needed=flagged_in(rankings, "not_needed"),
        signature=tuple(left),
        within_noise={"baseline": before, "after": choice.after} | ({"base": choice.based} if offered else {}),
        steps=tuple(steps),
        rings=rings,
        reranked=tuple(tuple(ranking) for ranking in rankings[1:]),
        chain=tuple(chosen_steps),
        started_from=fixed,
        base=tuple(base_fit),
        base_unused=tuple(e.id for e in offered if all(e is not kept for kept in base)),
        suspect_rings=suspects,
        touch_outliers=outliers,
        shapes=tuple(shapes),
        hybrid=hybrid,
        nested=honest,
    )
