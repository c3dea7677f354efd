"""Scene objects of one browser: the PH20 head, the ring with its magnified curves, the error field.

Each object owns its viser handles (created in that client's scene) and updates them from plain
arrays; the caller groups the updates of one slider move in one `client.atomic()` batch.
Lengths in mm, pivot of the head at the origin, z up (ph_explorer.geometry's conventions).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Callable, Mapping

import numpy as np
import trimesh
from numpy.typing import NDArray

from ph_explorer.geometry import Geometry, joint_angles, point_angles_deg, stylus_direction

# One color per curve (RGB 0-255), shared by the scene, the legend and the charts.
CURVE_COLORS: dict[str, tuple[int, int, int]] = {
    "measured": (30, 30, 30),
    "repetitions": (150, 150, 150),
    "network": (31, 119, 180),
    "trilinear": (230, 120, 20),
    "hybrid": (40, 160, 60),
    "reference": (120, 120, 120),
}
BAND_COLORS: dict[str, tuple[int, int, int]] = {
    "network": (150, 190, 235),
    "trilinear": (250, 200, 150),
    "hybrid": (160, 220, 160),
}


def curve_color(name: str) -> tuple[int, int, int]:
    return CURVE_COLORS.get(name, (140, 60, 160))


def hex_color(rgb: tuple[int, int, int]) -> str:
    return "#%02x%02x%02x" % tuple(int(c) for c in rgb)


# -- rotations as quaternions (viser wants wxyz) -------------------------------------------------------


def quat_z(angle_deg: float) -> NDArray[np.float64]:
    h = np.radians(angle_deg) / 2.0
    return np.array([np.cos(h), 0.0, 0.0, np.sin(h)])


def quat_x(angle_deg: float) -> NDArray[np.float64]:
    h = np.radians(angle_deg) / 2.0
    return np.array([np.cos(h), np.sin(h), 0.0, 0.0])


def quat_mul(p: NDArray[np.float64], q: NDArray[np.float64]) -> NDArray[np.float64]:
    w1, v1 = p[0], p[1:]
    w2, v2 = q[0], q[1:]
    return np.concatenate([[w1 * w2 - v1 @ v2], w1 * v2 + w2 * v1 + np.cross(v1, v2)])


def quat_head(a_deg: float, b_deg: float) -> NDArray[np.float64]:
    """Quaternion of Rz(B) Rx(A) = geometry.head_rotation(A, B) = geometry.ring_frame(A, B)."""
    return quat_mul(quat_z(b_deg), quat_x(a_deg))


# -- where to look from ----------------------------------------------------------------------------------


def ring_camera(
    a_deg: float, b_deg: float, axial_distance_mm: float, distance_mm: float = 105.0, off_axis_deg: float = 62.0, shift_mm: float = 18.0
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Camera (position, look_at) in mm showing the ring obliquely from the head's side, the stylus behind it.

    The camera sits off the ring axis towards the A joint's axis (always horizontal), a little
    raised, so the ring plane, its curves and the stylus arm stay in view at any orientation. The
    look-at point is shifted to the camera's right so that the ring sits left of the side panel.
    """
    s = stylus_direction(a_deg, b_deg)
    centre = axial_distance_mm * s
    b = np.radians(b_deg)
    side = np.array([np.cos(b), np.sin(b), 0.0])  # the A axis after B: perpendicular to the stylus
    e = np.radians(off_axis_deg)
    direction = -np.cos(e) * s + np.sin(e) * side + np.array([0.0, 0.0, 0.12])
    position = centre + distance_mm * direction / np.linalg.norm(direction)
    right = np.cross(centre - position, [0.0, 0.0, 1.0])
    norm = np.linalg.norm(right)
    look_at = centre + (shift_mm * right / norm if norm > 1e-9 else 0.0)
    return position + (look_at - centre), look_at


def axis_camera(a_deg: float, b_deg: float, axial_distance_mm: float, distance_mm: float = 70.0) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Camera looking down the ring's axis from the head's side (the polar plot undistorted)."""
    s = stylus_direction(a_deg, b_deg)
    centre = axial_distance_mm * s
    b = np.radians(b_deg)
    side = np.array([np.cos(b), np.sin(b), 0.0])
    return centre - distance_mm * s + 4.0 * side, centre


# -- the PH20 / TP20 head, built with trimesh ----------------------------------------------------------


def _cylinder(radius: float, z0: float, z1: float, sections: int = 48) -> trimesh.Trimesh:
    mesh = trimesh.creation.cylinder(radius=radius, height=abs(z1 - z0), sections=sections)
    mesh.apply_translation((0.0, 0.0, 0.5 * (z0 + z1)))
    return mesh


def _x_cylinder(radius: float, x0: float, x1: float, sections: int = 48) -> trimesh.Trimesh:
    mesh = _cylinder(radius, x0, x1, sections)
    mesh.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (0, 1, 0)))
    return mesh


def _box(extents: tuple[float, float, float], centre: tuple[float, float, float]) -> trimesh.Trimesh:
    mesh = trimesh.creation.box(extents=extents)
    mesh.apply_translation(centre)
    return mesh


@dataclass(frozen=True)
class HeadPart:
    name: str  # scene path below /head
    mesh: trimesh.Trimesh
    color: tuple[int, int, int]


@lru_cache(maxsize=8)
def head_parts(pivot_to_ball_mm: float = 80.0, ball_diameter_mm: float = 2.0) -> tuple[HeadPart, ...]:
    """The head's meshes in the frame of the joint that carries them (mm, roughly a PH20 with a TP20).

    Quill mount (fixed), B body (turns about z), A knuckle + TP20 body + module + stylus + ruby ball
    (turn about the A axis, x, after B). At A = B = 0 the stylus points down and the ball centre
    is at (0, 0, -L).
    """
    length = float(pivot_to_ball_mm)
    ball_r = 0.5 * float(ball_diameter_mm)
    # TP20 body (13.2 mm diameter) and module; the stylus takes whatever length is left to the ball.
    body_top, body_bottom = -11.0, -11.0 - 0.42 * length
    module_bottom = body_bottom - 0.13 * length
    stylus_r = max(0.3, min(0.75, 0.5 * ball_r + 0.25))
    parts = (
        HeadPart("quill", _cylinder(25.0, 60.0, 78.0), (175, 180, 188)),
        HeadPart("quill_stub", _box((44.0, 44.0, 40.0), (0.0, 0.0, 98.0)), (205, 208, 212)),
        HeadPart("B/body", _cylinder(24.0, 13.0, 59.5), (60, 66, 78)),
        HeadPart("B/cheek_pos", _box((6.0, 22.0, 26.0), (17.0, 0.0, 3.0)), (60, 66, 78)),
        HeadPart("B/cheek_neg", _box((6.0, 22.0, 26.0), (-17.0, 0.0, 3.0)), (60, 66, 78)),
        HeadPart("B/A/knuckle", _x_cylinder(10.5, -14.0, 14.0), (95, 102, 115)),
        HeadPart("B/A/tp20_body", _cylinder(6.6, body_top, body_bottom), (150, 155, 165)),
        HeadPart("B/A/tp20_module", _cylinder(6.6, body_bottom, module_bottom), (40, 40, 45)),
        HeadPart("B/A/stylus", _cylinder(stylus_r, module_bottom, -length + 0.8 * ball_r, 16), (200, 200, 205)),
        HeadPart(
            "B/A/ball",
            trimesh.creation.icosphere(subdivisions=3, radius=ball_r).apply_translation((0.0, 0.0, -length)),
            (200, 20, 40),
        ),
    )
    return parts


class HeadScene:
    """The PH20 head: /head (fixed), /head/B turning about z, /head/B/A turning about x."""

    def __init__(self, scene: Any, geometry: Geometry) -> None:
        self.scene = scene
        self.root = scene.add_frame("/head", show_axes=False)
        self.b_frame = scene.add_frame("/head/B", show_axes=False)
        self.a_frame = scene.add_frame("/head/B/A", show_axes=False)
        self.parts: dict[str, Any] = {}
        for part in head_parts(geometry.pivot_to_ball_mm, geometry.ball_diameter_mm):
            self.parts[part.name] = scene.add_mesh_simple(
                f"/head/{part.name}",
                part.mesh.vertices,
                part.mesh.faces,
                color=part.color,
                flat_shading=False,
            )

    def update(self, a_deg: float, b_deg: float) -> None:
        self.b_frame.wxyz = quat_z(b_deg)
        self.a_frame.wxyz = quat_x(a_deg)


# -- the ring and its curves ------------------------------------------------------------------------------


def closed_polyline(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """(n, 3) points around a loop -> (n, 2, 3) segments closing it."""
    return np.stack([points, np.roll(points, -1, axis=0)], axis=1)


def ring_points(radius_mm: NDArray[np.float64] | float, theta_deg: NDArray[np.float64]) -> NDArray[np.float64]:
    """Points at radius r_k and angle theta_k in the ring plane (ring frame: e1 = x, e2 = y), (n, 3)."""
    t = np.radians(theta_deg)
    r = np.broadcast_to(np.asarray(radius_mm, dtype=float), t.shape)
    return np.stack([r * np.cos(t), r * np.sin(t), np.zeros_like(t)], axis=-1)


def magnified_radius(bore_radius_mm: float, magnification: float, deviation_um: NDArray[np.float64]) -> NDArray[np.float64]:
    """R + magnification * dev: the polar roundness plot's radius in mm for deviations in um."""
    return bore_radius_mm + magnification * np.asarray(deviation_um, dtype=float) * 1e-3


def _annulus(inner: float, outer: float, height: float) -> trimesh.Trimesh:
    outer_c = trimesh.creation.cylinder(radius=outer, height=height, sections=96)
    ring = trimesh.creation.annulus(r_min=inner, r_max=outer, height=height, sections=96)
    return ring if ring is not None else outer_c


class RingScene:
    """The ring gauge with its axis along the stylus, and the polar plot of the curves in its plane."""

    CURVES = ("measured", "network", "trilinear", "hybrid")

    def __init__(self, scene: Any, geometry: Geometry) -> None:
        self.scene = scene
        self.geometry = geometry
        self.bore_radius = 0.5 * geometry.bore_diameter_mm
        self.frame = scene.add_frame("/ring", show_axes=False)
        gauge = _annulus(self.bore_radius + 0.6, self.bore_radius + 7.0, 5.0)
        # The gauge sits below the measuring plane (away from the head) so the curves stay visible.
        gauge.apply_translation((0.0, 0.0, -3.1))
        self.gauge = scene.add_mesh_simple(
            "/ring/gauge", gauge.vertices, gauge.faces, color=(185, 170, 120), opacity=0.35, side="double"
        )
        self.theta = point_angles_deg(geometry.points_per_circle)
        fine = np.linspace(0.0, 360.0, 181)[:-1]
        self.reference = scene.add_line_segments(
            "/ring/reference",
            closed_polyline(ring_points(self.bore_radius, fine)),
            CURVE_COLORS["reference"],
            thickness=1.5,
            thickness_units="screen",
        )
        self._fine = fine
        self.grid = scene.add_line_segments(
            "/ring/grid_1um",
            np.zeros((2, 2, 3)),
            (200, 200, 200),
            thickness=1.0,
            thickness_units="screen",
        )
        self.curves: dict[str, Any] = {}
        for name in self.CURVES:
            self.curves[name] = scene.add_line_segments(
                f"/ring/curves/{name}",
                np.zeros((1, 2, 3)),
                curve_color(name),
                thickness=3.0 if name == "measured" else 2.5,
                thickness_units="screen",
                visible=False,
            )
        self.repetitions = scene.add_line_segments(
            "/ring/curves/repetitions",
            np.zeros((1, 2, 3)),
            CURVE_COLORS["repetitions"],
            thickness=1.0,
            thickness_units="screen",
            visible=False,
        )
        self.band: Any = None
        self.band_model: str | None = None
        self.labels = [
            scene.add_label(
                f"/ring/point_{k}",
                str(k),
                position=tuple(ring_points(self.bore_radius + 9.0, np.array([self.theta[k]]))[0]),
                anchor="center-center",
                font_screen_scale=0.7,
            )
            for k in range(0, geometry.points_per_circle, max(1, geometry.points_per_circle // 4))
        ]
        self.title = scene.add_label(
            "/ring/title", "", position=(0.0, -(self.bore_radius + 14.0), 0.0), anchor="center-center", font_screen_scale=0.8
        )
        self.points: dict[str, NDArray[np.float64]] = {}  # the drawn curve points, for tests and picking

    def place(self, a_deg: float, b_deg: float) -> None:
        """Ring axis along s(A0, B0) through the pivot, its measuring plane at the ball's depth."""
        self.frame.wxyz = quat_head(a_deg, b_deg)
        self.frame.position = self.geometry.axial_distance_mm * stylus_direction(a_deg, b_deg)

    def update(
        self,
        curves: Mapping[str, NDArray[np.float64]],
        shown: Mapping[str, bool],
        magnification: float,
        repetitions: NDArray[np.float64] | None,
        show_repetitions: bool,
        band: tuple[str, NDArray[np.float64], NDArray[np.float64]] | None,
        title: str,
    ) -> None:
        grid = [ring_points(magnified_radius(self.bore_radius, magnification, d), self._fine) for d in (-1.0, 1.0)]
        self.grid.points = np.concatenate([closed_polyline(g) for g in grid]).astype(np.float32)
        self.points = {}
        for name, handle in self.curves.items():
            visible = name in curves and bool(shown.get(name, True))
            if visible:
                pts = ring_points(magnified_radius(self.bore_radius, magnification, curves[name]), self.theta)
                self.points[name] = pts
                handle.points = closed_polyline(pts).astype(np.float32)
            handle.visible = visible
        if repetitions is not None and show_repetitions:
            radius = magnified_radius(self.bore_radius, magnification, repetitions)  # (n_rep, n_pt)
            pts = ring_points(radius, np.broadcast_to(self.theta, radius.shape))  # (n_rep, n_pt, 3)
            segs = np.concatenate([closed_polyline(p) for p in pts])
            self.repetitions.points = segs.astype(np.float32)
            self.repetitions.visible = True
        else:
            self.repetitions.visible = False
        self._update_band(band, magnification)
        self.title.text = title

    def _update_band(self, band: tuple[str, NDArray[np.float64], NDArray[np.float64]] | None, magnification: float) -> None:
        if band is None:
            if self.band is not None:
                self.band.visible = False
            return
        model, low, high = band
        n = low.size
        inner = ring_points(magnified_radius(self.bore_radius, magnification, low), self.theta)
        outer = ring_points(magnified_radius(self.bore_radius, magnification, high), self.theta)
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


# -- the error field over the stylus directions ---------------------------------------------------------

# A few stops of the viridis colormap (0..1 -> RGB): perceptually uniform, colour-blind safe.
_VIRIDIS = np.array(
    [
        [68, 1, 84],
        [72, 40, 120],
        [62, 74, 137],
        [49, 104, 142],
        [38, 130, 142],
        [31, 158, 137],
        [53, 183, 121],
        [109, 205, 89],
        [180, 222, 44],
        [253, 231, 37],
    ],
    dtype=float,
)


def colormap(values: NDArray[np.float64], low: float, high: float) -> NDArray[np.uint8]:
    """Viridis colours (n, 3) uint8 for values scaled from [low, high]; NaN -> grey."""
    v = np.asarray(values, dtype=float)
    t = np.clip((v - low) / (high - low if high > low else 1.0), 0.0, 1.0)
    x = t * (len(_VIRIDIS) - 1)
    i = np.clip(np.floor(x).astype(int), 0, len(_VIRIDIS) - 2)
    w = (x - i)[..., None]
    rgb = (1 - w) * _VIRIDIS[i] + w * _VIRIDIS[i + 1]
    rgb = np.where(np.isfinite(v)[..., None], rgb, 170.0)
    return rgb.astype(np.uint8)


@lru_cache(maxsize=2)
def _hemisphere(radius: float, a_max_deg: float = 118.0) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """An icosphere cut to the stylus directions the head reaches (A <= a_max), vertices and faces."""
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=radius)
    a, _ = joint_angles(sphere.vertices)
    keep = (a[sphere.faces] <= a_max_deg).all(axis=1)
    mesh = trimesh.Trimesh(sphere.vertices, sphere.faces[keep], process=False)
    mesh.remove_unreferenced_vertices()
    return np.asarray(mesh.vertices), np.asarray(mesh.faces)


class ErrorField:
    """A hemisphere of stylus directions around the head coloured by a per-orientation figure.

    The colour of a direction is the value of the nearest measured orientation (a Voronoi map: no
    interpolation is invented). Measured orientations are markers (held-out ones larger); the
    current orientation is a highlighted marker where the stylus points.
    """

    def __init__(self, scene: Any, radius_mm: float = 300.0, opacity: float = 0.22) -> None:
        self.scene = scene
        self.opacity = opacity
        self.radius = radius_mm
        self.vertices, self.faces = _hemisphere(radius_mm)
        self.vertex_dirs = self.vertices / np.linalg.norm(self.vertices, axis=1, keepdims=True)
        self.surface: Any = None
        self.markers: Any = None
        self.orientations = np.zeros((0, 2))
        self.values = np.zeros(0)
        self.range = (0.0, 1.0)
        marker = trimesh.creation.icosphere(subdivisions=1, radius=1.0)
        self._marker = marker
        self.current = scene.add_icosphere("/field/current", radius=7.0, color=(220, 30, 30), subdivisions=3)
        self.current_line = scene.add_line_segments(
            "/field/current_line", np.zeros((1, 2, 3)), (220, 30, 30), thickness=1.0, thickness_units="screen"
        )
        self.visible = True
        self._on_pick: Callable[[float, float], None] | None = None

    def on_pick(self, callback: Callable[[float, float], None]) -> None:
        self._on_pick = callback

    def set_values(self, orientations: NDArray[np.float64], values: NDArray[np.float64], held_out: NDArray[np.bool_]) -> None:
        """Recolour the surface and the markers for a new figure or a new campaign."""
        self.orientations = np.asarray(orientations, dtype=float)
        self.values = np.asarray(values, dtype=float)
        finite = self.values[np.isfinite(self.values)]
        self.range = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
        dirs = stylus_direction(self.orientations[:, 0], self.orientations[:, 1])
        nearest = np.argmax(self.vertex_dirs @ dirs.T, axis=1)
        colors = colormap(self.values[nearest], *self.range)
        mesh = trimesh.Trimesh(self.vertices, self.faces, process=False)
        # Translucent and double-sided so the head and the ring stay visible through the field.
        material = trimesh.visual.material.PBRMaterial(
            baseColorFactor=[255, 255, 255, int(255 * self.opacity)], alphaMode="BLEND", doubleSided=True, roughnessFactor=0.9
        )
        mesh.visual = trimesh.visual.TextureVisuals(material=material)
        mesh.visual.vertex_attributes["color"] = np.column_stack([colors, np.full(len(colors), 255)]).astype(np.uint8)
        if self.surface is not None:
            self.surface.remove()
        self.surface = self.scene.add_mesh_trimesh("/field/surface", mesh, visible=self.visible, cast_shadow=False, receive_shadow=False)
        positions = dirs * self.radius * 1.01
        scales = np.where(np.asarray(held_out, dtype=bool), 6.0, 3.5)
        if self.markers is not None:
            self.markers.remove()
        self.markers = self.scene.add_batched_meshes_simple(
            "/field/markers",
            self._marker.vertices,
            self._marker.faces,
            batched_wxyzs=np.tile([1.0, 0.0, 0.0, 0.0], (len(positions), 1)),
            batched_positions=positions,
            batched_scales=scales,
            batched_colors=colormap(self.values, *self.range),
            visible=self.visible,
        )

        @self.markers.on_click
        def _(event: Any) -> None:
            i = event.instance_index
            if i is not None and self._on_pick is not None and 0 <= i < len(self.orientations):
                self._on_pick(float(self.orientations[i, 0]), float(self.orientations[i, 1]))

    def pick(self, index: int) -> None:
        """What a click on marker `index` does (also used by tests)."""
        if self._on_pick is not None:
            self._on_pick(float(self.orientations[index, 0]), float(self.orientations[index, 1]))

    def set_visible(self, visible: bool) -> None:
        self.visible = visible
        for handle in (self.surface, self.markers):
            if handle is not None:
                handle.visible = visible
        self.current.visible = visible
        self.current_line.visible = visible

    def highlight(self, a_deg: float, b_deg: float, ball_distance_mm: float) -> None:
        s = stylus_direction(a_deg, b_deg)
        self.current.position = s * self.radius * 1.01
        self.current_line.points = np.array([[s * ball_distance_mm, s * self.radius]], dtype=np.float32)
