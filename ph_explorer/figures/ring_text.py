"""Rings in words, for the renderer of the diagnosis record (figures.diagnosis_text): the rings
that exceed their noise, worst first, with the test that flagged each, the suspect rings to
remeasure and the touch outliers. Method: docs/diagnosis.md.
"""

from __future__ import annotations

from ph_explorer.campaign import orientation_label
from ph_explorer.diagnosis.results import Diagnosis, Ring
from ph_explorer.diagnosis.suspect import SUSPECT_LEVEL, SuspectRing
from ph_explorer.diagnosis.touch_outliers import OUTLIER_SHARE, OUTLIER_Z, TouchOutliers


def suspect_text(ring: SuspectRing) -> str:
    """'Remeasure A45 B40 (left out of the fit and the claims): ...' (diagnosis.suspect)."""
    label = orientation_label(ring.a_deg, ring.b_deg)
    # The test's own figures, in its one unit (a mean square over what noise gives it, 1 is noise),
    # beside the MAE over the floor that the record and the other ring lines give.
    standing = (
        f"{ring.ratio:.1f}x its floor out of sample (its mean square {ring.excess:.0f}x what noise gives it, "
        f"while {'the rings predicting it and the other check rings' if ring.check_ring else 'the rings predicting it'} "
        f"stay within {max(ring.neighbours_excess, 1.0):.1f}x theirs)"
    )
    if ring.check_ring:
        return (
            f"Remeasure {label} (a check ring, kept in every test): {standing}: a ring measured badly, or an error at this "
            "orientation alone; if it repeats, measure rings between it and its neighbours."
        )
    where = f"Remeasure {label} (left out of the fit and the claims): "
    if ring.reason == "fails alone":
        return where + f"{standing}: a ring measured badly, or an error at this orientation alone."
    return where + f"its repetitions disagree beyond noise (scatter test p = {ring.p_scatter:.2g}, level {SUSPECT_LEVEL:g} over the rings)."


def outliers_text(outliers: TouchOutliers) -> str:
    """'Touch outliers: 1.7 % of the touches ...' (diagnosis.touch_outliers)."""
    most = ", ".join(f"{orientation_label(a, b)} ({n})" for a, b, n in outliers.rings)
    return (
        f"Touch outliers: {100 * outliers.share:.2f} % of the touches ({outliers.count} of {outliers.touches}) read more than "
        f"{OUTLIER_Z:g} robust sigmas off their point's other repetitions, up to {outliers.largest_um:.2f} um; healthy touch "
        f"noise gives at most {100 * OUTLIER_SHARE:.1f} %: debris or a sticking trigger. Clean the stylus and the ring; "
        f"most are on {most}. The fit and the tests read each at its point's repetition median."
    )


def exceeding_text(count: int) -> str:
    """'1 ring exceeds its noise', '3 rings exceed their noise'."""
    return "1 ring exceeds its noise" if count == 1 else f"{count} rings exceed their noise"


def ring_reason(ring: Ring) -> str:
    """By which of the ring test's two statistics the ring exceeds (docs/methods/within_noise.md)."""
    return "by the scatter between its repetitions (harmonics 2-8)" if ring.by_scatter else "by its repetition mean"


def unvouched_check_rings(result: Diagnosis) -> list[Ring]:
    """The check rings that exceed their noise and are not named as measured badly (diagnosis.suspect), worst first."""
    suspects = {(s.a_deg, s.b_deg) for s in result.suspect_rings}
    return [r for r in result.failing_rings() if r.held_out and (r.a_deg, r.b_deg) not in suspects]


def unvouched_check_text(result: Diagnosis, next_rings: str) -> str:
    """What a `none` leaves to measure: the unvouched check rings (unvouched_check_rings) with their
    ratios and the rings to measure next; empty when there are none. The check rings are judged as
    a group, so no claim rests on them, but nothing vouches for them either (docs/diagnosis.md)."""
    rings = unvouched_check_rings(result)
    if not rings:
        return ""
    labels = [f"{orientation_label(r.a_deg, r.b_deg)} ({r.ratio:.1f}x its floor)" for r in rings]
    named = labels[0] if len(labels) == 1 else ", ".join(labels[:-1]) + " and " + labels[-1]
    one = len(rings) == 1
    it = "it" if one else "them"
    return (
        f"the campaign as a whole is within noise, but the check ring{'' if one else 's'} {named} "
        f"exceed{'s its' if one else ' their'} noise (each ring's test is at the 1 % level: a check ring in a hundred exceeds by "
        f"chance). The check rings are judged together, so {len(rings)} of {sum(r.held_out for r in result.rings)} "
        f"make{'s' if one else ''} no claim, and nothing vouches for {it} either: measure {it} again and the next rings "
        f"({next_rings}), then diagnose again. If it repeats, the model misses there: an error of the head the lattice rings do not resolve."
    )


def worst_ring_lines(result: Diagnosis, limit: int | None) -> list[str]:
    """How many rings exceed their noise, then the worst (all when limit is None), each with the test that flagged it."""
    if not result.tested:
        return ["One repetition: no ring can be tested against its noise."]
    rings = result.failing_rings()
    worst = f"; the worst {limit}, by out-of-sample MAE over its own floor:" if limit is not None and len(rings) > limit else "."
    lines = [
        f"Under the baseline {len(rings)} of {len(result.rings)} rings exceed their noise, out of sample (the within-noise test of each ring, level 1 %){worst}"
    ]
    for ring in rings[:limit]:
        kind = "check ring" if ring.held_out else "leave-one-out"
        lines.append(
            f"{orientation_label(ring.a_deg, ring.b_deg)} ({kind}): MAE {ring.mae_um['mean']:.3f} um, {ring.ratio:.1f}x its floor; exceeds {ring_reason(ring)}"
        )
    return lines
