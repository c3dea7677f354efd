"""The error history in words, for the renderer of the diagnosis record (figures.diagnosis_text):
each step's check-ring MAE against its floor, then the honest after of the nested cross-validation.
Method: docs/diagnosis.md.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from ph_explorer.diagnosis.results import NestedAfter, Step


def step_label(step: Step, name: Callable[[str], str] = str) -> str:
    """'baseline (trilinear)' or '+ b_axis_cyclic (hybrid, trilinear data part)': one step of the history."""
    if not step.added:
        return f"baseline ({step.model})" if step.model else "baseline"
    return name("+ " + " + ".join(step.added) + (f" ({step.model})" if step.model else ""))


def mae_text(mae: dict[str, float], floor: dict[str, float]) -> str:
    return f"mean {mae['mean']:.3f} (floor {floor['mean']:.3f})   single {mae['single']:.3f} (floor {floor['single']:.3f})"


def history_lines(steps: Sequence[Step], nested: NestedAfter | None) -> list[str]:
    """Each step's check-ring MAE and floor, then the honest after (nested_lines)."""
    lines = [f"{step_label(step):50s} {mae_text(step.mae_um, step.noise_floor_um)}" for step in steps]
    return lines + (nested_lines(nested) if nested is not None else [])


def nested_rings(nested: NestedAfter) -> str:
    """'the 135 rings, 10 of them check rings': what the folds predicted."""
    if not nested.check_rings:
        return f"the {nested.rings} training rings (the check rings above took part in the choice)"
    return f"the {nested.rings} rings, {nested.check_rings} of them check rings"


def nested_summary(nested: NestedAfter) -> str:
    """The honest after in one sentence: what the nested cross-validation measures."""
    return (
        f"The same, out of sample: the claims fitted, each at the period its scan prefers there, without the rings they predict ({nested.folds}-fold "
        f"cross-validation over {nested_rings(nested)}, trilinear data part):"
    )


def nested_lines(nested: NestedAfter) -> list[str]:
    """The nested cross-validation's lines: the error history's last."""
    return [
        nested_summary(nested),
        f"{'  before':50s} " + mae_text(nested.before_um, nested.noise_floor_um),
        f"{'  after':50s} " + mae_text(nested.after_um, nested.noise_floor_um),
        f"  set in the folds: {chosen_text(nested)}",
        *([f"  {gain_text(nested)}"] if nested.gain is not None else []),
    ]


def gain_text(nested: NestedAfter) -> str:
    """The nested gain's test over rings: whether the fall in error replicates on rings that took no part in choosing."""
    gain = nested.gain
    test = f"sign-flip p = {gain.p_value:.3g}, {gain.p_without_top:.3g} without the top ring; {gain.rings_gaining} of the {gain.rings} rings whose error the claims change gain"
    # A record of the training rings alone was written before the test was a claim's condition.
    withdrawn = "no effect the search chose is claimed" if nested.check_rings else "the check rings above carry the claims"
    verdict = "replicated" if nested.gain_holds else f"not replicated: {withdrawn}"
    return f"the fall in error on these rings, tested over them ({test}): {verdict}"


def chosen_text(nested: NestedAfter, name: Callable[[str], str] = str) -> str:
    """'b_axis_cyclic 22 cycles/rev (5 of 5), ...': the settings the folds chose for the claims, each with how many folds."""
    return ", ".join(f"{name(label)} ({n} of {nested.folds})" for label, n in nested.chosen_counts().items()) or "nothing"
