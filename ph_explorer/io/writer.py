"""Writing a campaign: the CSV (deterministic text) and its sidecar TOML, both atomically.

rep and point are written 0-based; dev_um to 1e-5 um and t_s to 1e-3 s, so the same campaign
always gives byte-identical files. Each file goes to a temporary file beside its target, then all
are renamed into place: a failure leaves nothing half-written behind.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from ph_explorer.campaign import Campaign
from ph_explorer.errors import InputError
from ph_explorer.io.sidecar import sidecar_path, sidecar_text


def write_campaign(campaign: Campaign, path: str | os.PathLike[str]) -> Path:
    """Write the campaign CSV (A_deg,B_deg,rep,point,dev_um[,t_s]) and its sidecar TOML, atomically.

    Returns the CSV path.
    """
    path = Path(path)
    if not np.isfinite(campaign.deviations).all():
        raise InputError("the campaign holds non-finite deviations; nothing written", file=str(path))
    atomic_write([(path, csv_text(campaign)), (sidecar_path(path), sidecar_text(campaign))])
    return path


def angle_text(x: float) -> str:
    """A short, exact-enough, deterministic text for an orientation angle (deg)."""
    text = f"{x + 0.0:.10g}"
    return "0" if text == "-0" else text


def csv_text(campaign: Campaign) -> str:
    """The campaign's CSV, one row per touch in (orientation, repetition, point) order."""
    n_o, n_rep, n_pt = campaign.deviations.shape
    o_idx, r_idx, p_idx = np.indices((n_o, n_rep, n_pt)).reshape(3, -1)
    a_text = np.array([angle_text(v) for v in campaign.orientations[:, 0]], dtype=object)[o_idx]
    b_text = np.array([angle_text(v) for v in campaign.orientations[:, 1]], dtype=object)[o_idx]
    # +0.0 turns -0.0 into 0.0 so "-0.00000" never appears.
    dev = np.round(campaign.deviations.ravel(), 5) + 0.0
    columns = [a_text, b_text, r_idx, p_idx, [f"{v:.5f}" for v in dev.tolist()]]
    header = ["A_deg", "B_deg", "rep", "point", "dev_um"]
    if campaign.times_s is not None:
        t = np.round(campaign.times_s.ravel(), 3) + 0.0
        columns.append([f"{v:.3f}" for v in t.tolist()])
        header.append("t_s")
    body = "\n".join(",".join(map(str, row)) for row in zip(*columns))
    return ",".join(header) + "\n" + body + "\n"


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write(targets: list[tuple[Path, str]]) -> None:
    """Write every text to a temp file beside its target, then move them all into place."""
    temps: list[tuple[str, Path]] = []
    try:
        for target, text in targets:
            target.parent.mkdir(parents=True, exist_ok=True)
            fd, temp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
            temps.append((temp, target))
            os.chmod(temp, 0o666 & ~_umask())  # mkstemp makes 0600; give the usual mode of a new file
            with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as handle:
                handle.write(text)
        for temp, target in temps:
            os.replace(temp, target)
    finally:
        for temp, _ in temps:
            if os.path.exists(temp):
                os.unlink(temp)
