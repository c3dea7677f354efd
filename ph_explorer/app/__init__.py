"""The explorer (`ph-explorer serve`): the only part of ph_explorer that imports viser.

server (ExplorerApp, build_server) -> session (one browser: wiring, rendering, data) -> scene
(head, ring, cameras), field (the error field), panels and physics_panel (the side panels),
physics (the diagnose -> refit loop), dataset (the campaign, its models and derived figures),
orientation_view (what is drawn at one orientation),
render_queue (the one render thread; plain threading, no viser).
"""
