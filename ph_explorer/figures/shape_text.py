"""A shape no catalog holds in words and drawn (diagnosis.shapes.Shape): its name, its lines in the
report, where more rings would pin it down, and its curve with its band. Method: docs/methods/shapes.md."""

from __future__ import annotations

import numpy as np

from ph_explorer.diagnosis.replication import REPLICATION_LEVEL
from ph_explorer.diagnosis.search import MATERIAL_REDUCTION
from ph_explorer.diagnosis.shapes import Shape
from ph_explorer.effects.environment import SECONDS_PER_HOUR
from ph_explorer.effects.error_functions import SHAPE_GROUPS, SHAPE_VARIABLES
from ph_explorer.figures.charts import line_chart_svg


def shape_name(shape: Shape) -> str:
    """'angular positioning of the B axis as a function of the B joint angle' (or its untold groups)."""
    name = f"{shape.words} as a function of the {shape_variable_words(shape)}"
    if not shape.untold:
        return name
    return f"{name}, or {' or '.join(untold_words(shape))} (these rings cannot tell)"


def untold_words(shape: Shape) -> list[str]:
    """The groups these rings cannot tell from the shape's, in words, in their order; every group of
    one axis as one ('any error motion of the B axis', 'any other ...' beside a group of its own)
    rather than three or four names in a row."""
    told = {*shape.untold, shape.group}
    words: list[str] = []
    for group in shape.untold:
        axis = SHAPE_GROUPS[group].axis
        every = {k for k, spec in SHAPE_GROUPS.items() if spec.axis == axis}
        if axis is not None and len(every) > 2 and every <= told:
            text = f"any {'other ' if shape.group in every else ''}error motion of the {axis} axis"
        else:
            text = SHAPE_GROUPS[group].words
        if text not in words:
            words.append(text)
    return words


def hours_text(seconds: float) -> str:
    """A touch time in hours, as every text of a shape or a signature words it ('33.5 h')."""
    return f"{seconds / SECONDS_PER_HOUR:.3g} h"


def variable_value(variable: str, value: float) -> str:
    """A value of a shape's variable in its unit: an angle in deg, a touch time in hours."""
    if variable == "time_s":
        return hours_text(value)
    if variable == "campaign_fraction":
        return f"{100.0 * value:.0f} % of the touch order"
    unit = SHAPE_VARIABLES[variable].unit
    return f"{value:.4g}{(' ' + unit) if unit else ''}"


def shape_variable_words(shape: Shape) -> str:
    return SHAPE_VARIABLES[shape.variable].label.split(" (")[0]


def pin_text(shape: Shape) -> str:
    """Where more rings would narrow its band: the angle where the band is widest; for a function of
    time (a probe that changes), rings measured again over a new campaign, since no ring can be
    measured at a time that has passed."""
    at = variable_value(shape.variable, shape.widest_at)
    if SHAPE_VARIABLES[shape.variable].angle:
        return f"measure rings whose {shape_variable_words(shape)} passes {at}, where its band is widest"
    return (
        f"measure some rings again at intervals over a new campaign (a probe that changes shows as the same ring read "
        f"differently); its band is widest at {at} into this one"
    )


def shape_lines(shape: Shape) -> list[str]:
    """A shape: what it is, its size with U (k = 2), its period and the aliasing limit, its test."""
    values, spread = np.array(shape.value), np.array(shape.U)
    peak = np.unravel_index(int(np.argmax(np.abs(values))), values.shape)
    symbol, unit = shape.components[peak[0]]
    test = shape.replication
    status = "claimed" if shape.claimed else "not claimed"
    if shape.claimed:
        why = ""
    elif shape.family_p >= REPLICATION_LEVEL:
        why = f" (its gain over rings is not significant as the best of the groups tried: p = {shape.family_p:.3g})"
    elif test.p_without_top >= REPLICATION_LEVEL:
        why = f" (it does not survive leaving out its most influential ring: p = {test.p_without_top:.3g} without it)"
    elif shape.rival is not None:
        group, fall = shape.rival
        why = (
            f" (the first look's best, {SHAPE_GROUPS[group].words}, predicts the check rings better: their error "
            f"{'falls' if fall >= 0 else 'rises'} {100 * abs(fall):.0f} % with it, {100 * shape.check_reduction:.0f} % with this one)"
        )
    elif not shape.plausible:
        limit = SHAPE_GROUPS[shape.group].plausible[1]
        why = f" (implausible: its curve reaches {np.abs(values).max():.3g} {unit}, beyond the {limit:g} {unit} an error motion of its kind reaches)"
    else:
        why = f" (not material: the check rings' error falls less than {f'{100 * MATERIAL_REDUCTION:.0f} %'} and it brings too few rings within noise)"
    lines = [
        f"{shape_name(shape)}: {status}{why}.",
        f"  Largest {symbol} {values[peak]:+.3g} +- {spread[peak]:.2g} {unit} (k = 2) at {variable_value(shape.variable, shape.x[peak[1]])}; "
        f"check rings' error {'-' if shape.check_reduction >= 0 else '+'}{100 * abs(shape.check_reduction):.0f} %, "
        f"{shape.rings_brought_within} ring{'' if shape.rings_brought_within == 1 else 's'} brought within noise; gain over rings p = {shape.family_p:.3g} as the best of the groups "
        f"(its own test's p = {test.p_value:.3g}, {test.p_without_top:.3g} without its top ring, before the groups' correction).",
    ]
    if shape.leave_out == "row":
        lines.append(
            "  Judged with each inner A row's rings predicted from the rows beside it (a second look, its p doubled): "
            "a ring's neighbours in its own row carry an error of the A joint."
        )
    if shape.aliasing_deg is not None:
        period = f"its curve is mostly {shape.period_cycles:g} cycles/rev; " if shape.period_cycles is not None else ""
        gap = (
            f" Between their sweeps, gaps up to {shape.unsampled_deg:.3g} deg are sampled by no ring: there the curve is interpolated."
            if shape.unsampled_deg is not None
            else ""
        )
        lines.append(
            f"  {period}these rings resolve periods down to {shape.aliasing_deg:.3g} deg ({360.0 / shape.aliasing_deg:.0f} cycles/rev) "
            f"where they sweep: shorter ones alias.{gap}"
        )
    return lines


# Each component's curve, and its band (k = 2) in a lighter shade of the same colour.
SHAPE_COLORS = (("#1f77b4", "#9ecae1"), ("#d62728", "#f4a6a6"), ("#2ca02c", "#a1d99b"), ("#9467bd", "#cbb7e3"))


def shape_svg(shape: Shape) -> str:
    """The shape's curve against its variable with its band (k = 2), one colour per component, in
    the spirit of ISO 230-7's error-motion plots (the same chart in the explorer and the report)."""
    x = np.array(shape.x)
    label = SHAPE_VARIABLES[shape.variable].label
    if shape.variable == "time_s":  # a campaign lasts hours: its time axis in hours (variable_value's unit)
        x, label = x / SECONDS_PER_HOUR, "touch time (h)"
    series, bands = [], []
    for (symbol, _), value, spread, (dark, light) in zip(shape.components, shape.value, shape.U, SHAPE_COLORS):
        value, spread = np.array(value), np.array(spread)
        series.append((symbol, value, dark))
        bands.append((f"{symbol} +- U (k = 2)", value - spread, value + spread, light))
    units = sorted({unit for _, unit in shape.components})
    status = "claimed" if shape.claimed else "not claimed"
    return line_chart_svg(x, series, f"Shape ({status}): {shape.words}", label, f"error ({', '.join(units)})", bands)
