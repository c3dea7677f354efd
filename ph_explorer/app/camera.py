"""One browser's camera: the View chosen ('ring + head', 'along the axis', 'whole field'), kept on
the ring while it follows the sliders (docs/explorer.md, "Orientation")."""

from __future__ import annotations

import threading
from collections.abc import Callable

import numpy as np
import viser

from ph_explorer.app.ring import RingScene
from ph_explorer.app.scene import CAMERA_FOV_DEG, DEFAULT_ASPECT, HeadScene, view_camera

# A change of the canvas's aspect (width / height) beyond this fraction places the View again: the
# browser docks its side panels after the first placement (1440x900: aspect 1.6, then 0.70).
ASPECT_TOLERANCE = 0.05


class ViewCamera:
    """One browser's camera at a View, kept on the ring while it follows the sliders.

    A View click (a callback thread) and a following camera (the render threads) both place it:
    one placement at a time, so a follow that read the View before a click never undoes the click.
    `scene()` gives the browser's head and ring as they are now (the ring's geometry is the head's).
    """

    def __init__(self, client: viser.ClientHandle, scene: Callable[[], tuple[HeadScene, RingScene]]) -> None:
        self.client, self._scene = client, scene
        self.view = "ring + head"
        self._at: tuple[float, float] | None = None  # the orientation and the chart's size it was placed for
        self._extent = 0.0
        self._aspect = DEFAULT_ASPECT  # the canvas's aspect it was placed for
        self._lock = threading.RLock()

    def look(self, view: str, a_deg: float, b_deg: float) -> None:
        """Point the camera: 'ring + head', 'along the axis' or 'whole field', at the ring drawn at (A, B)."""
        with self._lock:
            head, ring = self._scene()
            camera = self.client.camera
            extent, aspect = ring.extent_mm, self._canvas_aspect()
            position, look_at, up = view_camera(view, a_deg, b_deg, ring.geometry, extent, aspect)
            with self.client.atomic():  # position first: viser moves look_at along with it
                camera.fov = float(np.radians(CAMERA_FOV_DEG))  # the field of view the Views are framed for (sent when it differs)
                # Along the axis the camera looks through the head: hidden there, shown in the other views.
                head.set_visible(view != "along the axis")
                ring.show_labels(view != "whole field")  # there the ring is a few pixels wide
                camera.position, camera.look_at, camera.up_direction = position, look_at, up
            self._at, self._extent, self._aspect, self.view = (a_deg, b_deg), extent, aspect, view

    def _canvas_aspect(self) -> float:
        """The aspect of the browser's canvas as it last reported it (DEFAULT_ASPECT before it has)."""
        return float(getattr(self.client.camera, "aspect", 0.0) or DEFAULT_ASPECT)

    def reframe(self) -> None:
        """The browser's canvas changed shape (its panels docked, its window resized): the View placed
        again for it, so that what it shows fits the new canvas; an orbit (same shape) keeps its camera."""
        with self._lock:
            if self._at is not None and abs(self._canvas_aspect() / self._aspect - 1.0) > ASPECT_TOLERANCE:
                self.look(self.view, *self._at)

    def follow(self, a_deg: float, b_deg: float, resume: bool = False) -> None:
        """Keep the View on the ring drawn at (A, B) if either moved; `resume`: back to following, out of the whole field."""
        with self._lock:
            if resume and self.view == "whole field":
                self.view = "ring + head"
            moved = resume or self._at != (a_deg, b_deg) or abs(self._scene()[1].extent_mm - self._extent) > 1.0
            if moved and self.view != "whole field":
                self.look(self.view, a_deg, b_deg)
