"""The flat SVG charts (ph_explorer.figures.charts): the shared axes, what each chart writes."""

from __future__ import annotations

import re

import numpy as np

from ph_explorer.diagnosis.results import Step
from ph_explorer.figures.charts import bar_chart_svg, history_svg, line_chart_svg, nice_ticks, step_names, wrapped


def texts(svg: str) -> list[str]:
    return [re.sub(r"<[^>]+>", "", t) for t in re.findall(r"<text[^>]*>(.*?)</text>", svg)]


def step(added: list[str], mean: float) -> Step:
    return Step(added, {"mean": mean, "single": mean + 0.1}, {"mean": 0.043, "single": 0.136}, model="trilinear")


def test_the_history_names_each_step_on_its_axis_and_keeps_a_long_name_in_its_slot() -> None:
    steps = [
        step([], 0.15),
        step(["b_axis_tilt_motion"], 0.06),
        step(["b_axis_tilt_motion"], 0.06),
        step(["b_axis_tilt_motion", "a_axis_radial_motion"], 0.05),
    ]
    assert step_names(steps) == ["baseline", "+ b_axis_tilt_motion", "refitted", "+ a_axis_radial_motion"]
    svg = history_svg(steps)
    # Four slots of ~91 px: a long id is broken after an underscore, never in a word.
    assert "".join(wrapped("+ a_axis_radial_motion", 15)) == "+ a_axis_radial_motion"
    assert all(len(line) <= 15 for line in wrapped("+ a_axis_radial_motion", 15))
    assert ">baseline</tspan>" in svg and "MAE vs mean" in texts(svg) and texts(svg).count("its noise floor") == 2
    assert 'stroke-dasharray="5 4"' in svg  # the floors dashed, in the plot and in the legend
    assert "+ b_axis_tilt_motion: 0.060 um vs mean, floor 0.043" in svg  # each point's figures on hover


def test_line_and_bar_charts_use_round_ticks_and_name_their_series() -> None:
    x = np.arange(64.0)
    curve = 0.3 * np.sin(2 * np.pi * 3 * x / 64)
    svg = line_chart_svg(x, [("measured mean", curve, "#000000")], "Deviation against point number", "point number", "deviation (um)")
    labels = texts(svg)
    for tick in nice_ticks(0.0, 63.0):
        assert f"{tick:g}" in labels
    assert "measured mean" in labels and "deviation (um)" in labels and "point number" in labels
    bars = bar_chart_svg(np.arange(2, 21), [("measured mean", np.linspace(0.1, 0.0, 19), "#000000")], "Harmonics", "UPR", "amplitude (um)")
    assert bars.count("<rect") == 1 + 19 + 1  # the frame, a bar per UPR, the legend's swatch
    assert "<title>measured mean, 2: 0.1</title>" in bars
