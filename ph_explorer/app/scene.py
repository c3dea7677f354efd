"""Scene objects of one browser: the PH20 head (the ring and its polar chart are in ring.py, the
error field in field.py), the curves' colours and the cameras that look at them.

Each object owns its viser handles (created in that client's scene) and updates them from plain
arrays; the caller groups the updates of one slider move in one `client.atomic()` batch.
Lengths in mm, pivot of the head at the origin, z up (ph_explorer.geometry's conventions).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import trimesh
import viser
from numpy.typing import NDArray

# The curves' colours are the core's (ph_explorer.figures.polar): a report draws them as the explorer does.
from ph_explorer.figures.polar import BAND_COLORS, CURVE_COLORS, curve_color, hex_color  # noqa: F401 (re-exported)
from ph_explorer.geometry import A_LIMIT_DEG, Geometry, stylus_direction

# -- rotations (viser wants wxyz quaternions) ---------------------------------------------------------


def joint_wxyz(a_deg: float, b_deg: float) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
    """(B joint, A joint, head) wxyz quaternions of Rz(B), Rx(A) and Rz(B) Rx(A) (geometry.head_rotation),
    in scalar arithmetic: qz(B) qx(A) = (cB cA, cB sA, sB sA, sB cA) with c, s of half the angles
    (a slider move needs three; viser.transforms' SO3 costs ~50 us each)."""
    half_a, half_b = math.radians(a_deg) / 2.0, math.radians(b_deg) / 2.0
    ca, sa, cb, sb = math.cos(half_a), math.sin(half_a), math.cos(half_b), math.sin(half_b)
    return (cb, 0.0, 0.0, sb), (ca, sa, 0.0, 0.0), (cb * ca, cb * sa, sb * sa, sb * ca)


def joint_matrices(a_deg: float, b_deg: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(Rz(B), Rz(B) Rx(A)) as geometry.rot_z and geometry.head_rotation give them, in scalar
    arithmetic (a following camera needs both; their stacked arrays cost ~50 us each)."""
    a, b = math.radians(a_deg), math.radians(b_deg)
    ca, sa, cb, sb = math.cos(a), math.sin(a), math.cos(b), math.sin(b)
    b_turn = np.array([(cb, -sb, 0.0), (sb, cb, 0.0), (0.0, 0.0, 1.0)])
    return b_turn, np.array([(cb, -sb * ca, sb * sa), (sb, cb * ca, -cb * sa), (0.0, sa, ca)])


def stylus_point(a_deg: float, b_deg: float, distance_mm: float) -> tuple[float, float, float]:
    """distance_mm along s(A, B) = Rz(B) Rx(A) (0, 0, -1) (geometry.stylus_direction), in scalar arithmetic."""
    a, b = math.radians(a_deg), math.radians(b_deg)
    sa = math.sin(a)
    return (-distance_mm * math.sin(b) * sa, distance_mm * math.cos(b) * sa, -distance_mm * math.cos(a))


# -- where to look from ----------------------------------------------------------------------------------


# The chart radius (mm, point numbers included) of a chart at the bore's radius.
CHART_EXTENT_MM = 26.0
# Vertical field of view of the browsers' cameras (deg; viser's default is 75): at 75 the top of the
# head, nearer the camera than the ring, was drawn twice its scale, so that a View showing the whole
# head left the ring small; at 40 the perspective is mild and the ring about a fifth larger.
CAMERA_FOV_DEG = 40.0


# The scene's canvas lies between the docked panels; narrower than tall at 1440x900 (632 x 900 px)
# and 1280x720 (472 x 720 px). A camera that has not reported its aspect is taken to have this one.
DEFAULT_ASPECT = 0.7
# What a View shows fills the canvas to 1 / FRAME_MARGIN of its half-width and half-height.
FRAME_MARGIN = 1.06
# "ring + head": the camera's direction from the ring, in the ring's frame: OFF_AXIS_DEG off the
# stylus towards the head, and AZIMUTH_DEG from e1 (point 0) towards e2 (point 16). Halfway between
# the point numbers, the stylus is drawn between 32 and 48 rather than through a number (at azimuth
# 0 it ran through 32), and at OFF_AXIS_DEG no part of the head hides the curves at any A.
OFF_AXIS_DEG = 62.0
AZIMUTH_DEG = 45.0
OFF_AXIS, AZIMUTH = math.radians(OFF_AXIS_DEG), math.radians(AZIMUTH_DEG)
# The chart's outline as a camera frames it: every 10 deg of theta, (cos, sin) in the ring plane.
_OUTLINE_THETA = np.radians(np.arange(0.0, 360.0, 10.0))
CHART_OUTLINE = np.column_stack([np.cos(_OUTLINE_THETA), np.sin(_OUTLINE_THETA)])


def fit_distance(extent_mm: float, aspect: float, margin: float = 1.2) -> float:
    """How far (mm) a camera stands for a disc of radius extent_mm, seen square, to fill the
    canvas to 1 / margin of its half-height or half-width, whichever is smaller (aspect = w / h)."""
    return margin * extent_mm / (np.tan(np.radians(0.5 * CAMERA_FOV_DEG)) * min(1.0, aspect))


def frame_points(
    points: NDArray[np.float64], reference: NDArray[np.float64], direction: NDArray[np.float64], aspect: float, margin: float = FRAME_MARGIN
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Camera (position, look_at) on the line `direction` (towards the camera, z up) that shows every
    point inside the canvas (aspect = w / h), as near as it can: the nearest distance at which the
    points' extreme rays fit the field of view both ways (in perspective: a point nearer the camera
    counts larger), looking at the middle of what they span, in the plane through `reference`."""
    dx, dy, dz = (float(v) for v in direction)
    norm = math.sqrt(dx * dx + dy * dy + dz * dz)
    dx, dy, dz = dx / norm, dy / norm, dz / norm
    across = math.hypot(dx, dy)
    # right = -d x z, up = right x -d, in scalar arithmetic (the camera follows every slider move)
    right = (-dy / across, dx / across, 0.0)
    up = (-dz * dx / across, -dz * dy / across, across)
    basis = np.array([(dx, dy, dz), right, up]).T  # columns: d, right, up
    depth, *offsets = ((np.asarray(points, dtype=float) - reference) @ basis).T  # depth: towards the camera
    distance, look_at = 0.0, np.asarray(reference, dtype=float).copy()
    tan_v = math.tan(math.radians(0.5 * CAMERA_FOV_DEG)) / margin
    for axis, offset, tan in ((basis[:, 1], offsets[0], tan_v * aspect), (basis[:, 2], offsets[1], tan_v)):
        # |offset - c| <= tan (D - depth) for every point: c in [high - tan D, low + tan D].
        high, low = float((offset + tan * depth).max()), float((offset - tan * depth).min())
        distance = max(distance, (high - low) / (2.0 * tan))
        look_at += 0.5 * (high + low) * axis
    return look_at + distance * basis[:, 0], look_at


def ring_camera(
    a_deg: float, b_deg: float, geometry: Geometry, extent_mm: float = CHART_EXTENT_MM, aspect: float = DEFAULT_ASPECT
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Camera (position, look_at) in mm showing the whole head and the ring's chart, obliquely from the head's side.

    The camera sits OFF_AXIS_DEG off the ring axis, towards the head, at AZIMUTH_DEG in the ring
    plane (between the point numbers), as near as it can with every part of the head and the chart
    (radius extent_mm) inside the canvas of this aspect (frame_points): the head is never cut off,
    and the ring, below or beside it, is as large as the head leaves room for.
    """
    frame = joint_matrices(a_deg, b_deg)[1]
    s = -frame[:, 2]  # the stylus direction (geometry.stylus_direction)
    direction = -math.cos(OFF_AXIS) * s + math.sin(OFF_AXIS) * (math.cos(AZIMUTH) * frame[:, 0] + math.sin(AZIMUTH) * frame[:, 1])
    centre = geometry.axial_distance_mm * s
    chart = centre + extent_mm * (CHART_OUTLINE @ frame[:, :2].T)
    head = head_points(a_deg, b_deg, geometry.pivot_to_ball_mm, geometry.ball_diameter_mm)
    return frame_points(np.concatenate([head, chart]), centre, direction, aspect)


def axis_camera(
    a_deg: float, b_deg: float, axial_distance_mm: float, extent_mm: float = CHART_EXTENT_MM, aspect: float = DEFAULT_ASPECT
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Camera (position, look_at, up) looking down the ring's axis from the head's side.

    The chart lies in a plane square to the view, so it is drawn undistorted, oriented as the
    panel's flat polar plot: e1 to the right, e2 up, theta counter-clockwise. It looks at the
    ring's centre from far enough for the whole chart to fit the canvas of this aspect (the head,
    between it and the ring, is hidden in this view).
    """
    e2 = joint_matrices(a_deg, b_deg)[1][:, 1]
    s = stylus_direction(a_deg, b_deg)
    centre = axial_distance_mm * s
    return centre - fit_distance(extent_mm, aspect) * s, centre, e2


# The whole error field (the dome of stylus directions, radius FIELD_RADIUS_MM) seen from outside:
# the camera's direction from the pivot, and the point it frames around.
FIELD_RADIUS_MM = 300.0
FIELD_DIRECTION = (560.0, -700.0, 420.0)
FIELD_CENTRE = (0.0, 0.0, -60.0)


def field_camera(aspect: float = DEFAULT_ASPECT) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Camera (position, look_at) showing the whole dome of stylus directions (A up to the limit) and the head."""
    a, b = np.meshgrid(np.linspace(0.0, A_LIMIT_DEG + 3.0, 12), np.arange(-180.0, 180.0, 15.0))
    dome = FIELD_RADIUS_MM * stylus_direction(a.ravel(), b.ravel())
    head = head_points(0.0, 0.0)
    return frame_points(np.concatenate([dome, head]), np.array(FIELD_CENTRE), np.array(FIELD_DIRECTION), aspect)


def view_camera(
    view: str, a_deg: float, b_deg: float, geometry: Geometry, extent_mm: float, aspect: float = DEFAULT_ASPECT
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(position, look_at, up) of a View button's camera: 'ring + head', 'along the axis', 'whole field'."""
    if view == "along the axis":
        return axis_camera(a_deg, b_deg, geometry.axial_distance_mm, extent_mm, aspect)
    if view == "whole field":
        position, look_at = field_camera(aspect)
    else:
        position, look_at = ring_camera(a_deg, b_deg, geometry, extent_mm=extent_mm, aspect=aspect)
    return position, look_at, np.array([0.0, 0.0, 1.0])


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


@lru_cache(maxsize=8)
def head_outline(pivot_to_ball_mm: float = 80.0, ball_diameter_mm: float = 2.0) -> tuple[NDArray[np.float64], ...]:
    """The head's convex outline in the frame of each joint: the vertices of the convex hulls of the
    fixed parts, of the parts B turns and of the parts A turns (what a View must show of it)."""
    groups: dict[str, list[trimesh.Trimesh]] = {"": [], "B": [], "B/A": []}
    for part in head_parts(pivot_to_ball_mm, ball_diameter_mm):
        groups[part.name.rpartition("/")[0]].append(part.mesh)
    return tuple(np.asarray(trimesh.util.concatenate(meshes).convex_hull.vertices) for meshes in groups.values())


def head_points(a_deg: float, b_deg: float, pivot_to_ball_mm: float = 80.0, ball_diameter_mm: float = 2.0) -> NDArray[np.float64]:
    """The head's outline (head_outline) with its joints at (A, B), in the scene's frame (mm)."""
    fixed, b_parts, a_parts = head_outline(float(pivot_to_ball_mm), float(ball_diameter_mm))
    b_turn, a_turn = joint_matrices(a_deg, b_deg)
    return np.concatenate([fixed, b_parts @ b_turn.T, a_parts @ a_turn.T])


class HeadScene:
    """The PH20 head: /head (fixed), /head/B turning about z, /head/B/A turning about x."""

    def __init__(self, scene: viser.SceneApi, geometry: Geometry) -> None:
        self.scene = scene
        self.root = scene.add_frame("/head", show_axes=False)
        self.b_frame = scene.add_frame("/head/B", show_axes=False)
        self.a_frame = scene.add_frame("/head/B/A", show_axes=False)
        self.parts: dict[str, viser.MeshHandle] = {}
        self._angles: tuple[float | None, float | None] = (None, None)  # (A, B) the joints were last turned to
        for part in head_parts(geometry.pivot_to_ball_mm, geometry.ball_diameter_mm):
            self.parts[part.name] = scene.add_mesh_simple(
                f"/head/{part.name}",
                part.mesh.vertices,
                part.mesh.faces,
                color=part.color,
                flat_shading=False,
            )

    def set_visible(self, visible: bool) -> None:
        """Hide the head (the along-axis view looks through where it stands)."""
        self.root.visible = visible

    def update(self, a_deg: float, b_deg: float) -> None:
        """Turn the joints; only a joint whose angle changed is sent (a slider moves one at a time)."""
        b_wxyz, a_wxyz, _ = joint_wxyz(a_deg, b_deg)
        last_a, last_b = self._angles
        if b_deg != last_b:
            self.b_frame.wxyz = b_wxyz
        if a_deg != last_a:
            self.a_frame.wxyz = a_wxyz
        self._angles = (a_deg, b_deg)
