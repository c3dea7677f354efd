"""Whether a campaign's rings give the trilinear model a lattice to interpolate on: what the diagnosis,
the explorer and every leave-one-out figure need of a campaign's design (docs/formats.md, "The rings
a campaign needs")."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

from ph_explorer.campaign import Campaign
from ph_explorer.errors import InputError
from ph_explorer.io import read_campaign
from ph_explorer.models.crossval import out_of_sample_weights


def require_lattice(campaign: Campaign) -> None:
    """Raise InputError, naming the campaign's file, when its training rings (the check rings aside:
    the sidecar's, else the rings off the lattice) are none, or leave none on a lattice of A0 rows
    sharing B0 columns once any one of them is left out: the trilinear model then has nothing to
    interpolate from. The weights made here are the ones the diagnosis uses next (crossval keeps
    them), so a campaign that passes pays nothing twice."""
    train = ~campaign.holdout_mask()
    try:
        lattice = bool(train.any()) and out_of_sample_weights(campaign.orientations, train) is not None
    except ValueError:  # the trilinear model's: no training ring on its lattice (models/trilinear.py)
        lattice = False
    if not lattice:
        held = (
            "the sidecar's check rings"
            if campaign.check_orientations is not None and len(campaign.check_orientations)
            else "those off any lattice, as no sidecar names check rings"
        )
        raise InputError(
            f"{int(train.sum())} of its {campaign.n_orientations} rings are left to train on ({held} held out), "
            "and they lie on no lattice of A0 rows sharing B0 columns: the trilinear model, the diagnosis's baseline, "
            "predicts a ring from the lattice rings around it; measure rings on a lattice "
            "(e.g. A0 every 15 deg, B0 every 20 deg; ph-explorer design --start proposes one)",
            file=campaign.source,
        )


def read_lattice_campaign(path: str | os.PathLike[str], geometry: Mapping[str, float] | None = None) -> Campaign:
    """A campaign file read (io.read_campaign) for a command that models it: its rings checked by
    require_lattice, so that a design without a lattice gets one line, not a failure deep inside."""
    campaign = read_campaign(Path(path), dict(geometry or {}))
    require_lattice(campaign)
    return campaign
