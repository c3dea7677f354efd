"""`ph-explorer serve`: start the 3D explorer, print its URL and when it was ready, serve until Ctrl-C."""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any

from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.errors import InputError


def serve_command(**options: Any) -> int:
    """Start the explorer with build_server's options (scenario, data, model, host, port, geometry,
    study, effects; default: the shipped paper campaign with assets/models/paper)."""
    # viser and torch: imported when the command runs, so that the CLI (and inspect) works without them.
    from ph_explorer.app.loading import LoadingNotice, open_server

    if options.get("scenario") is not None and options.get("data") is not None:
        raise InputError("give --scenario or --data, not both")
    # The page first (viser alone imports in a fraction of a second): the URL answers and says what
    # is loading while torch, the campaign and the models load.
    server = open_server(host=options.pop("host", "127.0.0.1"), port=options.pop("port", 8080), verbose=options.pop("verbose", False))
    notice = LoadingNotice(server)
    host = server.get_host()
    shown_host = "127.0.0.1" if host in ("0.0.0.0", "") else host
    answering = seconds_since_process_start()
    answered = f"{answering:.1f} s after the command started; " if answering is not None else ""
    print(f"ph-explorer: answering at http://{shown_host}:{server.get_port()}  ({answered}loading the campaign and the models)", flush=True)
    try:
        from ph_explorer.app.server import build_server

        app = build_server(**options, server=server, notice=notice)
    except BaseException:
        server.stop()
        raise
    try:  # from here a Ctrl-C stops the app, whenever it comes
        print(f"ph-explorer: {app.dataset.label}; models: {', '.join(app.dataset.model_names) or 'none'}")
        for note in app.dataset.notes:
            print(f"  - {note}")
        if options.get("effects") is not None:
            own = [effect_id for effect_id in app.shared.catalog if effect_id not in DEFAULT_CATALOG]
            print(f"ph-explorer: effects of {options['effects']}: {', '.join(own)} (candidates in every browser's Physics tab)")
        if app.study is not None:
            saved = app.study.current()
            count = 0 if saved is None else len(saved["runs"])
            runs = f"{count} run{'s' if count != 1 else ''} so far" if saved is not None else "new: written on the first Save study"
            print(f"ph-explorer: study {app.study.path} ({runs}); Save study writes this file and no other")
        since_start = seconds_since_process_start()
        # Benchmarks read this line in both forms.
        ready = f"ready {since_start:.1f} s after the command started" if since_start is not None else f"ready in {app.startup_s:.1f} s"
        print(f"ph-explorer: serving at http://{shown_host}:{app.port}  ({ready}; Ctrl-C stops)", flush=True)
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        print("ph-explorer: stopped")
    finally:
        app.stop()
    return 0


def seconds_since_process_start() -> float | None:
    """Wall-clock seconds since this process started (imports included), where /proc says; else None."""
    try:
        fields = Path("/proc/self/stat").read_text().rsplit(")", 1)[1].split()
        start_ticks = int(fields[19])  # field 22 of stat: start time in clock ticks after boot
        uptime = float(Path("/proc/uptime").read_text().split()[0])
        return max(0.0, uptime - start_ticks / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError):
        return None
