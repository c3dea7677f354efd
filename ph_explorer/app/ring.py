"""The ring gauge in the 3D scene and its polar roundness plot, drawn on the ring as an instrument's chart.

The chart follows ph_explorer.figures.polar: the least-squares reference circle at the chart's base
radius, scale circles, the curves at base + magnification x deviation (true scale in the scene's
mm), point numbers and the direction of theta. In 3D only the point numbers and theta are
written, apart from each other at the cameras of "ring + head" and "along the axis" (and hidden in
"whole field", where the ring is a few pixels wide); the flat polar plot beside the scene has the
full set: its title, the magnification and scale, each circle's value. The object owns its viser
handles; the session updates them inside one `client.atomic()` batch.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import trimesh
import viser
from numpy.typing import NDArray

from ph_explorer.app.scene import BAND_COLORS, CURVE_COLORS, curve_color, joint_wxyz, stylus_point
from ph_explorer.figures.polar import PolarScale, scale_label
from ph_explorer.geometry import Geometry, point_angles_deg

FINE_DEG = np.linspace(0.0, 360.0, 181)[:-1]  # a smooth circle


def closed_polyline(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """(n, 3) points around a loop -> (n, 2, 3) segments closing it."""
    return np.stack([points, np.roll(points, -1, axis=0)], axis=1)


def ring_points(radius_mm: NDArray[np.float64] | float, theta_deg: NDArray[np.float64]) -> NDArray[np.float64]:
    """Points at radius r_k and angle theta_k in the ring plane (ring frame: e1 = x, e2 = y), (n, 3)."""
    t = np.radians(theta_deg)
    r = np.broadcast_to(np.asarray(radius_mm, dtype=float), t.shape)
    return np.stack([r * np.cos(t), r * np.sin(t), np.zeros_like(t)], axis=-1)


def _annulus(inner: float, outer: float, height: float) -> trimesh.Trimesh:
    ring = trimesh.creation.annulus(r_min=inner, r_max=outer, height=height, sections=96)
    return ring if ring is not None else trimesh.creation.cylinder(radius=outer, height=height, sections=96)


def theta_arrow(radius_mm: float) -> NDArray[np.float64]:
    """Segments of an arc from point 0 towards increasing theta, with an arrowhead: (n, 2, 3)."""
    arc = ring_points(radius_mm, np.linspace(8.0, 32.0, 10))
    tip, back = arc[-1], ring_points(radius_mm, np.array([28.0]))[0]
    direction = (tip - back) / np.linalg.norm(tip - back)
    normal = np.array([-direction[1], direction[0], 0.0])
    size = 0.06 * radius_mm
    head = [tip - size * direction + 0.6 * size * normal, tip - size * direction - 0.6 * size * normal]
    return np.concatenate([np.stack([arc[:-1], arc[1:]], axis=1), np.array([[tip, head[0]], [tip, head[1]]])])


class RingScene:
    """The ring gauge with its axis along the stylus, and the polar chart of the curves in its plane."""

    CURVES = ("measured", "network", "trilinear", "gp", "hybrid")

    def __init__(self, scene: viser.SceneApi, geometry: Geometry) -> None:
        self.scene = scene
        self.geometry = geometry
        self.bore_radius = 0.5 * geometry.bore_diameter_mm
        self.frame = scene.add_frame("/ring", show_axes=False)
        gauge = _annulus(self.bore_radius + 0.6, self.bore_radius + 7.0, 5.0)
        # The gauge sits below the measuring plane (away from the head) so the curves stay visible.
        gauge.apply_translation((0.0, 0.0, -3.1))
        self.gauge = scene.add_mesh_simple("/ring/gauge", gauge.vertices, gauge.faces, color=(185, 170, 120), opacity=0.35, side="double")
        self.theta = point_angles_deg(geometry.points_per_circle)
        line = {"thickness_units": "screen"}
        # The least-squares reference circle (the chart's base circle) and the scale circles.
        self.reference = scene.add_line_segments("/ring/reference", np.zeros((1, 2, 3)), CURVE_COLORS["reference"], thickness=2.0, **line)
        self.grid = scene.add_line_segments("/ring/scale_circles", np.zeros((1, 2, 3)), (200, 200, 200), thickness=1.0, **line)
        self.arrow = scene.add_line_segments("/ring/theta_arrow", np.zeros((1, 2, 3)), (60, 60, 60), thickness=1.5, **line)
        self.arrow_label = scene.add_label(
            "/ring/theta_label", "θ", position=(0.0, 0.0, 0.0), anchor="center-center", font_screen_scale=0.8
        )
        self.curves: dict[str, viser.LineSegmentsHandle] = {}
        for name in self.CURVES:
            self.curves[name] = scene.add_line_segments(
                f"/ring/curves/{name}",
                np.zeros((1, 2, 3)),
                curve_color(name),
                thickness=3.0 if name == "measured" else 2.5,
                visible=False,
                **line,
            )
        self.repetitions = scene.add_line_segments(
            "/ring/curves/repetitions", np.zeros((1, 2, 3)), CURVE_COLORS["repetitions"], thickness=1.0, visible=False, **line
        )
        self.band: viser.MeshHandle | None = None
        self.band_model: str | None = None
        step = max(1, geometry.points_per_circle // 4)
        self.numbered = list(range(0, geometry.points_per_circle, step))
        self.labels = [
            scene.add_label(f"/ring/point_{k}", str(k), position=(0.0, 0.0, 0.0), anchor="center-center", font_screen_scale=0.7)
            for k in self.numbered
        ]
        self.title = ""  # what the chart shows (the flat polar plot writes it; tests read it here)
        self.scale: PolarScale | None = None  # the chart drawn last
        self._chart_drawn: tuple[PolarScale, float] | None = None  # what _update_chart last sent
        self.points: dict[str, NDArray[np.float64]] = {}  # the drawn curve points, for tests and picking
        # A slider move redraws every curve: its points are radius x these unit vectors, its segments
        # these pairs of point indices (k, k + 1), and a handle's visibility is sent only when it changes.
        self._unit = ring_points(1.0, self.theta)
        n = self.theta.size
        self._segments = np.stack([np.arange(n), (np.arange(n) + 1) % n], axis=1)
        self._visible: dict[str, bool] = {}
        self._profile_mm = 0.0  # the largest radius of the curves drawn last

    def place(self, a_deg: float, b_deg: float) -> None:
        """Ring axis along s(A0, B0) through the pivot, its measuring plane at the ball's depth."""
        self.frame.wxyz = joint_wxyz(a_deg, b_deg)[2]
        self.frame.position = stylus_point(a_deg, b_deg, self.geometry.axial_distance_mm)

    @property
    def extent_mm(self) -> float:
        """The chart's outer radius in the scene (point numbers included): what a camera must show."""
        return self._numbers_radius() + 6.0

    def _numbers_radius(self) -> float:
        scale = self.scale
        outer = max(scale.outer_mm if scale else self.bore_radius, self.bore_radius + 7.0, self._profile_mm)
        return outer + 4.0

    def show_labels(self, visible: bool) -> None:
        """The point numbers and theta's label: hidden when the camera is too far for them to stay apart."""
        for handle in [*self.labels, self.arrow_label]:
            self._show(handle.name, handle, visible)

    def _show(self, name: str, handle: viser.SceneNodeHandle, visible: bool) -> None:
        if self._visible.get(name) != visible:
            handle.visible = visible
            self._visible[name] = visible

    def update(
        self,
        curves: Mapping[str, NDArray[np.float64]],
        shown: Mapping[str, bool],
        scale: PolarScale,
        repetitions: NDArray[np.float64] | None,
        show_repetitions: bool,
        band: tuple[str, NDArray[np.float64], NDArray[np.float64]] | None,
        title: str,
    ) -> None:
        self.scale = scale
        self.points = {}
        profile = 0.0
        for name, handle in self.curves.items():
            visible = name in curves and bool(shown.get(name, True))
            if visible:
                radius = scale.radius_mm(curves[name])
                pts = radius[:, None] * self._unit
                self.points[name] = pts
                profile = max(profile, float(np.max(np.abs(radius))))
                handle.points = pts[self._segments].astype(np.float32)  # == closed_polyline(pts)
            self._show(name, handle, visible)
        self._profile_mm = profile
        if repetitions is not None and show_repetitions:
            radius = scale.radius_mm(repetitions)  # (n_rep, n_pt)
            pts = radius[:, :, None] * self._unit  # (n_rep, n_pt, 3)
            self.repetitions.points = pts[:, self._segments].reshape(-1, 2, 3).astype(np.float32)
        self._show("repetitions", self.repetitions, repetitions is not None and show_repetitions)
        self._update_band(band, scale)
        self._update_chart(scale)
        self.title = title

    def _update_chart(self, scale: PolarScale) -> None:
        """Reference and scale circles with their labels, point numbers, theta's direction, magnification.

        Sent only when the scale or the numbers' radius changed: most slider moves keep both."""
        numbers = self._numbers_radius()
        if self._chart_drawn == (scale, round(numbers, 1)):
            return
        self._chart_drawn = (scale, round(numbers, 1))
        self.reference.points = closed_polyline(ring_points(scale.base_mm, FINE_DEG)).astype(np.float32)
        others = [r for text, r in scale.labelled_circles() if text != scale_label(0.0)]
        circles = [closed_polyline(ring_points(r, FINE_DEG)) for r in others] or [np.zeros((1, 2, 3))]
        self.grid.points = np.concatenate(circles).astype(np.float32)
        for handle, k in zip(self.labels, self.numbered):
            handle.position = tuple(float(v) for v in ring_points(numbers, np.array([self.theta[k]]))[0])
        self.arrow.points = theta_arrow(numbers + 2.0).astype(np.float32)
        self.arrow_label.position = tuple(float(v) for v in ring_points(numbers + 5.0, np.array([20.0]))[0])

    def _update_band(self, band: tuple[str, NDArray[np.float64], NDArray[np.float64]] | None, scale: PolarScale) -> None:
        if band is None:
            if self.band is not None:
                self.band.visible = False
            return
        model, low, high = band
        n = low.size
        inner = ring_points(scale.radius_mm(low), self.theta)
        outer = ring_points(scale.radius_mm(high), self.theta)
        vertices = np.concatenate([inner, outer]) + np.array([0.0, 0.0, -0.05])
        k = np.arange(n)
        k1 = (k + 1) % n
        faces = np.concatenate([np.stack([k, k1, n + k], 1), np.stack([k1, n + k1, n + k], 1)])
        if self.band is None or self.band_model != model:
            if self.band is not None:
                self.band.remove()
            self.band = self.scene.add_mesh_simple(
                "/ring/band", vertices, faces, color=BAND_COLORS.get(model, (200, 200, 200)), opacity=0.6, side="double"
            )
            self.band_model = model
        else:
            self.band.vertices = vertices.astype(np.float32)
            self.band.visible = True
