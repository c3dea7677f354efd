"""Scene objects of one browser: the PH20 head and the ring with its magnified curves (the error
field is in field.py), their colours and the cameras that look at them.

Each object owns its viser handles (created in that client's scene) and updates them from plain
arrays; the caller groups the updates of one slider move in one `client.atomic()` batch.
Lengths in mm, pivot of the head at the origin, z up (ph_explorer.geometry's conventions).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Mapping

import numpy as np
import trimesh
import viser
from numpy.typing import NDArray
from viser.transforms import SO3

from ph_explorer.geometry import Geometry, point_angles_deg, stylus_direction

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


# -- rotations (viser wants wxyz quaternions; viser.transforms composes them) -------------------------


def b_joint(b_deg: float) -> SO3:
    """The B joint's rotation: about z."""
    return SO3.from_z_radians(np.radians(b_deg))


def a_joint(a_deg: float) -> SO3:
    """The A joint's rotation: about x, in the frame the B joint turned."""
    return SO3.from_x_radians(np.radians(a_deg))


def head_orientation(a_deg: float, b_deg: float) -> SO3:
    """Rz(B) Rx(A) = geometry.head_rotation(A, B) = geometry.ring_frame(A, B)."""
    return b_joint(b_deg) @ a_joint(a_deg)


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

    def __init__(self, scene: viser.SceneApi, geometry: Geometry) -> None:
        self.scene = scene
        self.root = scene.add_frame("/head", show_axes=False)
        self.b_frame = scene.add_frame("/head/B", show_axes=False)
        self.a_frame = scene.add_frame("/head/B/A", show_axes=False)
        self.parts: dict[str, viser.MeshHandle] = {}
        for part in head_parts(geometry.pivot_to_ball_mm, geometry.ball_diameter_mm):
            self.parts[part.name] = scene.add_mesh_simple(
                f"/head/{part.name}",
                part.mesh.vertices,
                part.mesh.faces,
                color=part.color,
                flat_shading=False,
            )

    def update(self, a_deg: float, b_deg: float) -> None:
        self.b_frame.wxyz = b_joint(b_deg).wxyz
        self.a_frame.wxyz = a_joint(a_deg).wxyz


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

    def __init__(self, scene: viser.SceneApi, geometry: Geometry) -> None:
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
        self.curves: dict[str, viser.LineSegmentsHandle] = {}
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
        self.band: viser.MeshHandle | None = None
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
        self.frame.wxyz = head_orientation(a_deg, b_deg).wxyz
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
