"""The within-noise tests of a diagnosis in words, for the renderer of the record
(figures.diagnosis_text): the campaign's test in one line, every test in full detail, and the
models they judge (the baseline, with the base model when there is one, with the effects found). Method: docs/diagnosis.md.
"""

from __future__ import annotations

from ph_explorer.diagnosis.results import Diagnosis
from ph_explorer.diagnosis.within_noise import CHECK_TOLERANCE, FALSE_ALARM, NoiseTest
from ph_explorer.effects import Catalog, effect_label


def tested_models(result: Diagnosis) -> list[tuple[str, str]]:
    """The models the record's within-noise tests judge, in order: (its key in within_noise, its words)."""
    tested = [("baseline", f"the baseline ({result.baseline_model})")]
    tested += [("base", "with the base model")] if result.base else []
    return tested + [("after", "with the effects found")]


def base_text(result: Diagnosis) -> str:
    """The base model in one line: its effects' parameters +- U, fitted and never claimed, and those
    these rings predict better without."""
    # A parameter whose column the rings cannot see (its fit 0 +- 0, e.g. an offset along the ring's
    # own axis) is said so, not given a value.
    unseen = [(e, k) for e, link in zip(result.chain, result.base) for k, u in link.params_u.items() if not u > 1e-9]
    fits = "; ".join(
        f"{effect_label(effect)} "
        + effect.parameters_text({k: v for k, v in link.params.items() if (effect, k) not in unseen}, link.params_u)
        for effect, link in zip(result.chain, result.base)
    )
    fits += " (+- U, k = 2)" + "".join(f"; {effect_label(e)} {k}: not seen by these rings" for e, k in unseen) if fits else ""
    unused = ", ".join(result.base_unused)
    return (
        "Base model, never claimed (the location errors an adaptive campaign's few rings cannot interpolate; the verdict "
        "judges what lies beyond them): "
        + (fits or "none")
        + (f"; not fitted, these rings predict rings left out better without: {unused}" if unused else "")
        + "."
    )


def campaign_test_line(result: Diagnosis) -> str:
    # The test the verdict rests on: with the claims, else with what is always in the model.
    key, model = tested_models(result)[-1 if result.verdict in ("missing", "partial") else -2]
    test = result.within_noise[key]
    if test is None:
        return "One repetition: no repetition spread, so 'within noise' could not be tested."
    outcome = "fails" if test.fails else "is within noise"
    return (
        f"Within-noise test, {model}: the campaign {outcome} ({test.failing_rings} of {test.rings} rings exceed their noise; "
        f"test statistic {test.statistic:.1f}, failing above {test.critical:.1f} for a {100 * FALSE_ALARM:.0f} % false-alarm rate, p = {test.p_value:.3g}"
        + (f"; {check_group_text(test)}" if test.check_exceedance is not None else "")
        + ")."
    )


def check_group_text(test: NoiseTest) -> str:
    """'the check rings together 1.3x their noise level, within (fail above 2)'."""
    verdict = "fail" if test.check_rings_fail else "within"
    return f"the check rings together {test.check_exceedance:.1f}x their noise level, {verdict} (fail above {CHECK_TOLERANCE:g})"


def test_lines(result: Diagnosis, catalog: Catalog) -> list[str]:
    """The noise floor, the baseline and every within-noise test (full detail)."""
    floor, baseline = result.noise_floor_um, result.baseline_mae_um
    lines = [
        f"Noise floor (touch noise after the modelled effects): {floor['mean']:.3f} um against the repetition mean, "
        f"{floor['single']:.3f} um against single repetitions.",
        f"Baseline ({result.baseline_model}) on the {int(result.held_out.sum())} held-out rings: "
        f"MAE {baseline['mean']:.3f} um (mean), {baseline['single']:.3f} um (single).",
    ]
    for key, model in tested_models(result):
        test = result.within_noise.get(key)
        if test is not None:
            quiet = test.failing_rings and not test.fails
            lines.append(
                f"Within-noise test, {model}: by how much the rings exceed their noise, summed over all rings but the worst: "
                f"{test.statistic:.1f}; the campaign fails above {test.critical:.1f} (p = {test.p_value:.3g})"
                + (": within noise, though a few rings exceed at the ring level (1 %), as noise alone makes some." if quiet else ".")
            )
    lines += [
        f"Not needed: {c.effect} ({catalog[c.effect].parameters_text(c.params, c.params_u)}) would lower the check rings' error by "
        f"{100 * c.error_reduction:.0f} %, but the model is within noise without it: nothing the campaign shows is missing, so it is not claimed."
        for c in result.not_needed
    ]
    return lines
