"""The error field of one browser: the dome of stylus directions around the head, coloured by a
per-orientation figure, with a marker per measured orientation (click one to go there).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache

import numpy as np
import trimesh
import viser
from numpy.typing import NDArray

from ph_explorer.figures.orientation_map import colormap, value_range
from ph_explorer.geometry import A_LIMIT_DEG, joint_angles, stylus_direction


@lru_cache(maxsize=2)
def _hemisphere(radius: float, a_max_deg: float = A_LIMIT_DEG + 3.0) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """An icosphere cut to the stylus directions the head reaches (A <= a_max, a few degrees of margin
    so the faces along the edge stay), vertices and faces."""
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

    def __init__(self, scene: viser.SceneApi, radius_mm: float = 300.0, opacity: float = 0.22) -> None:
        self.scene = scene
        self.opacity = opacity
        self.radius = radius_mm
        self.vertices, self.faces = _hemisphere(radius_mm)
        self.vertex_dirs = self.vertices / np.linalg.norm(self.vertices, axis=1, keepdims=True)
        self.surface: viser.GlbHandle | None = None
        self.markers: viser.BatchedMeshHandle | None = None
        self.orientations = np.zeros((0, 2))
        self.values = np.zeros(0)
        self.range = (0.0, 1.0)
        marker = trimesh.creation.icosphere(subdivisions=1, radius=1.0)
        self._marker = marker
        # Context, off by default (the Map tab's flat map is what is read): shown on request.
        self.visible = False
        self.current = scene.add_icosphere("/field/current", radius=7.0, color=(220, 30, 30), subdivisions=3, visible=False)
        self.current_line = scene.add_line_segments(
            "/field/current_line", np.zeros((1, 2, 3)), (220, 30, 30), thickness=1.0, thickness_units="screen", visible=False
        )
        self._on_pick: Callable[[float, float], None] | None = None
        self._at: tuple[float, float, float] | None = None  # the current orientation's marker, drawn when shown

    def on_pick(self, callback: Callable[[float, float], None]) -> None:
        self._on_pick = callback

    def set_values(self, orientations: NDArray[np.float64], values: NDArray[np.float64], held_out: NDArray[np.bool_]) -> None:
        """Recolour the surface and the markers for a new figure or a new campaign."""
        self.orientations = np.asarray(orientations, dtype=float)
        self.values = np.asarray(values, dtype=float)
        self.range = value_range(self.values)
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
        def _(event: viser.SceneNodePointerEvent[viser.BatchedMeshHandle]) -> None:
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
        if visible and self._at is not None:
            self.highlight(*self._at)

    def highlight(self, a_deg: float, b_deg: float, ball_distance_mm: float) -> None:
        """Mark the current orientation; while the field is hidden only remembered (a slider move sends nothing)."""
        self._at = (a_deg, b_deg, ball_distance_mm)
        if not self.visible:
            return
        s = stylus_direction(a_deg, b_deg)
        self.current.position = s * self.radius * 1.01
        self.current_line.points = np.array([[s * ball_distance_mm, s * self.radius]], dtype=np.float32)
