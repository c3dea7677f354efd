"""The Map tab of one browser: which figure the error map over orientations shows (the map itself, an
SVG drawn by the core, sits in the figures panel beside the controls), the rings that fail (a
button each), a ring picker that goes there, and the 3D field's switch.

viser's HTML element reports no click inside it, so a ring is reached by the "Go to ring"
dropdown (every ring, largest value first) or by a failing ring's button. The panel formats what
the core returns (ph_explorer.figures.orientation_map, Diagnosis.failing_rings); it computes nothing.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import viser
from numpy.typing import NDArray

from ph_explorer.app.panels import NO_CHOICE, orientation_label
from ph_explorer.diagnosis.results import Ring
from ph_explorer.figures.orientation_map import MapFigure, map_svg, ranked_rings
from ph_explorer.figures.ring_text import exceeding_text

MAX_FAILING_BUTTONS = 10  # the worst rings get a button each; the map's verdict shows the rest


def failing_label(ring: Ring) -> str:
    """A failing ring's button: where, its error and floor in um, how far above its floor."""
    kind = ", check ring" if ring.held_out else ""
    by = ", by its repetitions' scatter" if ring.by_scatter else ""  # its mean may be under its floor
    return f"{orientation_label(ring.a_deg, ring.b_deg)}: {ring.mae_um['mean']:.3f} um, floor {ring.floor_um['mean']:.3f} um ({ring.ratio:.1f}x{kind}{by})"


class MapPanel:
    """Which figure the map shows, the map, a ring picker, where it fails, and the 3D field's switch."""

    def __init__(self, gui: viser.GuiApi, names: Sequence[str], go_to: Callable[[float, float], None], plot: viser.GuiHtmlHandle) -> None:
        self.gui = gui
        self._go_to = go_to
        self.figure = gui.add_dropdown(
            "Map of",
            tuple(names),
            hint="a value per measured ring: roundness, a model's out-of-sample error, its ratio to the floor, the diagnosis's verdict",
        )
        self.plot = plot  # the map itself, drawn in the figures panel (always in view)
        # Where it fails right under the map's choice (all ten buttons above the fold at 1440x900), then the map's note and picker.
        with gui.add_folder("Where it fails") as self.failing_folder:
            self.failing_text = gui.add_markdown("")
        self.note = gui.add_markdown("")
        self.ring = gui.add_dropdown("Go to ring", (NO_CHOICE,), hint="every ring of the map, largest value first")
        self.ring_targets: dict[str, tuple[float, float]] = {}
        self.ring.on_update(lambda _: self._go(self.ring.value, self.ring_targets))
        self.failing_buttons: list[viser.GuiButtonHandle] = []
        self.failing_targets: dict[str, tuple[float, float]] = {}
        self.show = gui.add_checkbox("3D field around the head", False, hint="the same figure on the dome of stylus directions (context)")
        self._shown: tuple[MapFigure, NDArray[np.float64], NDArray[np.bool_], str] | None = None
        self._current: tuple[float, float] | None = None
        self.proposed: NDArray[np.float64] | None = None
        self.set_failing(None)

    def _go(self, label: str, targets: dict[str, tuple[float, float]]) -> None:
        if label in targets:
            self._go_to(*targets[label])

    def set_names(self, names: Sequence[str]) -> None:
        """The figures of new data (or of a diagnosis); a figure the data no longer has gives way to the first."""
        if self.figure.value not in names:
            self.figure.value = names[0]
        self.figure.options = tuple(names)

    def computing(self) -> None:
        self.plot.content = "<em>computing the map…</em>"
        self.note.content = ""

    def set_figure(self, name: str, figure: MapFigure, orientations: NDArray[np.float64], check: NDArray[np.bool_]) -> None:
        """A new figure (or campaign): the rings' values; drawn with the current orientation by `draw`."""
        self._shown = (figure, np.asarray(orientations, dtype=float), np.asarray(check, dtype=bool), name)
        self.note.content = f"_{name}: {figure.note}._"
        self.ring_targets = {f"{orientation_label(a, b)} ({figure.text(v)})": (a, b) for a, b, v in ranked_rings(figure, orientations)}
        self.ring.options = (NO_CHOICE, *self.ring_targets)
        self.ring.value = NO_CHOICE

    def draw(self, a_deg: float, b_deg: float) -> None:
        """The map with the current orientation marked (and the rings proposed, crossed)."""
        self._current = (a_deg, b_deg)
        if self._shown is not None:
            figure, orientations, check, name = self._shown
            self.plot.content = map_svg(figure, orientations, check, (a_deg, b_deg), name, self.proposed)

    def propose(self, rings: NDArray[np.float64] | None) -> None:
        """Rings to measure next (the rings that would decide), crossed on the map; None: none."""
        self.proposed = rings
        if self._current is not None:
            self.draw(*self._current)

    def set_failing(self, rings: Sequence[Ring] | None, tested: bool = True, baseline: str = "") -> None:
        """The rings that fail, worst first, a button each; before a diagnosis, say so. baseline: the
        model the diagnosis predicts the check rings with (the map may show another)."""
        for button in self.failing_buttons:
            button.remove()
        self.failing_buttons, self.failing_targets = [], {}
        if rings is None:
            self.failing_text.content = "_Not diagnosed yet: **Diagnose** (Physics tab) tests every ring against its noise._"
            return
        if not tested:
            self.failing_text.content = "_One repetition: no repetition spread, so no ring can be tested against its noise._"
            return
        if not rings:
            self.failing_text.content = "**No ring exceeds its noise** (the within-noise test, ring level 1 %)."
            return
        more = (
            f" The first {MAX_FAILING_BUTTONS} have a button; the map's ring verdict shows all." if len(rings) > MAX_FAILING_BUTTONS else ""
        )
        scatter = (
            " A ring marked 'by its repetitions' scatter' exceeds by the scatter between its repetitions (harmonics 2-8), "
            "the test's second statistic, though its mean may lie under its floor."
            if any(ring.by_scatter for ring in rings)
            else ""
        )
        self.failing_text.content = (
            f"**{exceeding_text(len(rings))}** by the within-noise test (ring level 1 %), worst first (out-of-sample MAE vs "
            f"the mean / its floor; a check ring as {baseline or 'the baseline'} predicts it, a training ring left out); "
            f"click to go there.{scatter}{more}"
        )
        with self.failing_folder:
            for ring in rings[:MAX_FAILING_BUTTONS]:
                label = failing_label(ring)
                button = self.gui.add_button(label)
                self.failing_targets[label] = (ring.a_deg, ring.b_deg)
                button.on_click(lambda event: self._go(event.target.label, self.failing_targets))
                self.failing_buttons.append(button)
