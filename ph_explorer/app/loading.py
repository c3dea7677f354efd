"""The page first: a viser server that answers at once and tells each browser what is still loading.

`ph-explorer serve` opens it before it imports torch and loads the campaign and the models (seconds
on a small machine), so that the URL answers within a second and a browser opened early reads
"Loading ..." instead of an unanswered address; ExplorerApp then takes over the same server and
gives every browser, early or late, its session. This module imports viser only.
"""

from __future__ import annotations

import threading

import viser

LOADING_TEXT = "**Loading {what}…** The explorer appears here when ready."
# The scene's light: a sky-and-ground light instead of viser's default environment map, whose HDR
# image each browser prefilters on load: without a GPU (software WebGL) that stalled the page for
# ~4 s, no frame drawn and no click taken (Debian's chromium, SwiftShader). The same matte look.
HEMISPHERE_LIGHT = {"sky_color": (255, 255, 255), "ground_color": (140, 140, 140), "intensity": 2.0}


def open_server(host: str = "127.0.0.1", port: int = 8080, verbose: bool = False) -> viser.ViserServer:
    """A viser server with the explorer's theme and panel placement (port 0 picks a free port)."""
    server = viser.ViserServer(host=host, port=port, label="ph-explorer", verbose=verbose)
    server.gui.configure_theme(control_width="large", show_share_button=False, show_logo=False)
    # Docked full height on the right: the loop's controls stay above the fold (issue 15, item 4).
    server.gui.main_panel.dock_right()
    server.scene.set_up_direction("+z")
    server.scene.configure_environment_map(None)
    server.scene.add_light_hemisphere("/light", **HEMISPHERE_LIGHT)
    return server


class LoadingNotice:
    """A line in every browser that connects before the explorer is ready, saying what is loading."""

    def __init__(self, server: viser.ViserServer, what: str = "the campaign and the models") -> None:
        self._lock = threading.Lock()
        self._what = what
        self._ready = False
        self._notes: dict[int, viser.GuiMarkdownHandle] = {}
        server.on_client_connect(self._show)
        server.on_client_disconnect(self._forget)

    def _show(self, client: viser.ClientHandle) -> None:
        with self._lock:
            if not self._ready:
                self._notes[client.client_id] = client.gui.add_markdown(LOADING_TEXT.format(what=self._what))

    def _forget(self, client: viser.ClientHandle) -> None:
        with self._lock:
            self._notes.pop(client.client_id, None)

    def say(self, what: str) -> None:
        """Tell every waiting browser what is loading now."""
        with self._lock:
            self._what = what
            for note in self._notes.values():
                note.content = LOADING_TEXT.format(what=what)

    def finish(self) -> None:
        """Ready: remove the notes; browsers connecting from now on get no note."""
        with self._lock:
            self._ready = True
            notes, self._notes = list(self._notes.values()), {}
        for note in notes:
            note.remove()

    @property
    def waiting(self) -> int:
        """Browsers showing the note now."""
        with self._lock:
            return len(self._notes)
