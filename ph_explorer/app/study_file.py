"""The study the server's operator opened (`ph-explorer serve --study FILE`): checked before the
server starts, continued by each browser's physics loop, written back to that one file only.

A browser never names a path: the file is the operator's, the browser only asks to save. The
file's study is shared by every browser of the app; a browser saves on top of the study it opened
(or last saved), so a browser that opened an older version than the one on disk is refused
rather than allowed to drop another browser's run.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.study import Study, study_campaign
from ph_explorer.effects import Catalog, Effect
from ph_explorer.errors import InputError
from ph_explorer.io import checked_output_file, file_sha256

# The data-driven part every refit and diagnosis of the app uses (physics.py calls the core's defaults).
APP_DATA_PART = "trilinear"


class StudyFile:
    """The operator's study file, the campaign it belongs to, and the study as last written."""

    def __init__(self, path: Path, campaign: dict[str, Any], study: Study | None, catalog: Catalog) -> None:
        self.path = path
        self.campaign = campaign  # {"file", "sha256", "orientations", "repetitions"} of the served campaign
        self.catalog = catalog
        self._study = study  # None: the file does not exist yet (the first save creates it)
        self._lock = threading.Lock()

    @property
    def name(self) -> str:
        return self.path.name

    def current(self) -> Study | None:
        """The study as on disk now (as opened, or as a browser last saved it)."""
        with self._lock:
            return self._study

    def save(self, study: Study, previous: Study | None) -> None:
        """Write the next study, made on top of `previous`; refused if another browser saved since."""
        with self._lock:
            if self._study is not previous:
                runs = len(self._study.runs) if self._study is not None else 0
                raise InputError(
                    f"another browser saved this study (now run {runs}) since this one opened it: reload the page to continue from it",
                    file=str(self.path),
                )
            study.save(self.path)
            self._study = study


def open_study(path: Path, data_file: Path, campaign: Campaign, catalog: Catalog) -> StudyFile:
    """The study at `path` if it is one of this campaign's (same bytes as data_file), else an
    InputError line; a path that does not exist yet is a new study, written on the first save."""
    path = checked_output_file(path, "--study", "the study", "study.json")
    sha256 = file_sha256(Path(data_file))
    described = study_campaign(Path(data_file).name, sha256, campaign)
    study = None
    if path.exists():
        study = Study.load(path, catalog)  # every effect of the chain a candidate of this catalog, its history readable
        study.rings_added_on(sha256, str(data_file))
        if study.data_part != APP_DATA_PART:
            raise InputError(
                f"the study's data part is {study.data_part!r}; the explorer refits with the trilinear part "
                "(continue this study with ph-explorer diagnose --resume)",
                file=str(path),
            )
    return StudyFile(path, described, study, catalog)


def chain_of(study: Study | None, catalog: Catalog) -> list[Effect]:
    """The effects of the study's chain at their settings (none for a study not written yet)."""
    return [] if study is None else study.effects(catalog)
