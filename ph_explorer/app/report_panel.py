"""Studies and reports in the browser (issue 15, item 7): export the session as a report, open a study.

"Export report" sends the report of what this browser shows (its campaign and models, the last
diagnosis or the study it opened, the polar plot at its orientation) as one HTML file, made by
the core (ph_explorer.figures.html_report) exactly as `ph-explorer report` makes it, to the browser as a download.
"Open study" takes a study file from the browser (`diagnose --save`, or the explorer's Save study):
JSON data, checked by the core as `diagnose --resume` checks it (its format, its effects, its
history, and that it was made on the campaign shown); a bad file is one line here and the session
keeps what it had. An opened study continues in the physics loop: its history is the start of the
error history, Diagnose searches on from the model it reached and Refit fits that model + the
ticked effects. (Saving writes only the operator's file of `serve --study`: a browser never names
a path on the server.)
"""

from __future__ import annotations

import datetime
import re
from collections.abc import Callable
from concurrent.futures import Future
from typing import Any, Protocol

import viser

from ph_explorer.app.dataset import Dataset
from ph_explorer.app.physics import PhysicsLoop
from ph_explorer.app.study_file import APP_DATA_PART
from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.study import Study, study_campaign
from ph_explorer.effects import Catalog, effect_label
from ph_explorer.errors import InputError
from ph_explorer.figures.html_report import default_orientations, report_html
from ph_explorer.io import campaign_sha256, json_object_text, parse_json_object
from ph_explorer.io.rings import rings_csv_text


class Session(Protocol):
    """What the panel uses of its browser's session (app/session.py), which creates it."""

    dataset: Dataset
    loop: PhysicsLoop
    catalog: Catalog
    client: viser.ClientHandle

    @property
    def orientation(self) -> tuple[float, float]: ...

    def submit(self, job: Callable[..., None], *args: object) -> Future[None]: ...


def report_file_name(campaign: Campaign, label: str) -> str:
    """'report_head_3.html': the download's name, from the campaign's source (letters, digits, - and _ only)."""
    stem = (campaign.scenario or {}).get("name") or (campaign.source or label).rsplit("/", 1)[-1].rsplit(".", 1)[0]
    return "report_" + (re.sub(r"[^A-Za-z0-9_-]+", "_", str(stem)).strip("_") or "campaign") + ".html"


def shown_campaign(session: Session) -> tuple[str, str]:
    """The name and identity (sha256) of the campaign the browser shows: the operator's file while
    the server's study applies, else the bytes simulate --out or write_campaign would write for it."""
    loop, campaign = session.loop, session.dataset.campaign
    if loop.study is not None and loop.study_open:
        return loop.study.campaign["file"], loop.study.campaign["sha256"]
    name = (campaign.scenario or {}).get("name") or campaign.source or session.dataset.label
    return str(name), campaign_sha256(campaign)


def session_study(loop: PhysicsLoop, described: dict[str, Any]) -> Study | None:
    """The study this browser would save now: its last diagnosis with the model refitted last (a
    study's chain when it continues one, as Save study writes it), else the study it opened; None
    before either."""
    if loop.diagnosis is not None:
        if loop.study_open:
            chain = loop.refitted if loop.refitted is not None else loop.chain
            return Study.of_run(loop.diagnosis, chain, described, APP_DATA_PART, None, loop.previous, steps=loop.steps)
        if loop.refitted is not None:  # the model as refitted last and the history of every step
            return Study.of_run(loop.diagnosis, loop.refitted, described, APP_DATA_PART, steps=loop.steps)
        return Study.of_run(loop.diagnosis, loop.diagnosis.chain, described, APP_DATA_PART)
    return loop.previous if loop.study_open else None


class ReportPanel:
    """Export report (a download) and Open study (an upload), with one status line."""

    def __init__(self, gui: viser.GuiApi, session: Session) -> None:
        self.session = session
        with gui.add_folder("Study and report"):
            self.export = gui.add_button(
                "Export report", hint="one HTML file: the campaign, the map, polar plot and Tables 1-3, the diagnosis and its history"
            )
            # Shown for a teaching scenario only (Session.set_dataset: app/physics.py's teaching_scenario).
            self.reveal = gui.add_checkbox(
                "Name hidden effects in the report", False, visible=False, hint="teaching scenarios: the report names what the twin hid"
            )
            self.open = gui.add_upload_button(
                "Open study", mime_type=".json,application/json", hint="a study of the campaign shown (diagnose --save)"
            )
            self.download = gui.add_button(
                "Download study",
                hint="this browser's study as a file: its diagnosis and the model refitted last, on top of a study opened here",
            )
            self.status = gui.add_markdown("")
        self.export.on_click(lambda _: session.submit(self.export_report))
        self.open.on_upload(lambda _: session.submit(self.open_study, self.open.value.name, self.open.value.content))
        self.download.on_click(lambda _: session.submit(self.download_study))

    def reveal_hidden(self) -> None:
        """Reveal (Physics): what a teaching scenario hid, shown; this panel's checkbox is then ticked,
        so that what the report names is what the checkbox says (untick it to keep the report blind)."""
        loop = self.session.loop
        loop.reveal()
        self.reveal.value = bool(self.reveal.value) or loop.revealed

    def report(self) -> tuple[str, str, bool]:
        """The report of what this browser shows, its file name, and whether it holds a diagnosis."""
        s = self.session
        ds, loop = s.dataset, s.loop
        name, sha256 = shown_campaign(s)
        study = session_study(loop, study_campaign(name, sha256, ds.campaign))
        # The orientation on screen first, then where the diagnosis fails worst and a check ring.
        chosen = [s.orientation]
        for a, b in default_orientations(ds.campaign, ds.held_out_mask, loop.diagnosis):
            if ds.campaign.index_of(a, b) != ds.campaign.index_of(*chosen[0]):
                chosen.append((a, b))
        campaign = ds.campaign
        created = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
        models = {n: ds.models[n] for n in ds.model_names}
        text = report_html(
            campaign,
            models,
            ds.train_mask,
            s.catalog,
            chosen[:3],
            study,
            loop.diagnosis,
            reveal=bool(self.reveal.value),  # ticked by Reveal too (reveal_hidden)
            created=created,
            source=name,
            decision=loop.decision.as_dict() if loop.decision is not None else None,
        )
        return text, report_file_name(campaign, ds.label), study is not None

    def export_report(self) -> None:
        self.status.content = "_Writing the report…_"
        text, file_name, diagnosed = self.report()
        content = text.encode("utf-8")
        self.session.client.send_file_download(file_name, content, save_immediately=True)
        holds = "with its diagnosis" if diagnosed else "not diagnosed yet: Diagnose (Physics tab) or Open study first for its diagnosis"
        self.status.content = f"Report sent: **{file_name}** ({len(content) // 1024} KiB, one file, {holds})."

    def send_rings(self) -> None:
        """The rings that would decide (Physics tab), as the file `design --decide --out` writes."""
        decision = self.session.loop.decision
        if decision is not None and decision.rings:
            self.session.client.send_file_download("rings.csv", rings_csv_text(decision.rings).encode("utf-8"), save_immediately=True)

    def download_study(self) -> None:
        """The study Save study would write, sent to the browser as a file (diagnose --resume and Open
        study read it): a study opened by upload is continued and saved this way."""
        s = self.session
        name, sha256 = shown_campaign(s)
        study = session_study(s.loop, study_campaign(name, sha256, s.dataset.campaign))
        if study is None:
            self.status.content = "**Nothing to download** — diagnose first (Physics tab), or open a study."
            return
        file_name = report_file_name(s.dataset.campaign, s.dataset.label).replace("report_", "study_", 1).rsplit(".", 1)[0] + ".json"
        content = json_object_text(study.to_json()).encode("utf-8")
        s.client.send_file_download(file_name, content, save_immediately=True)
        runs = len(study.runs)
        self.status.content = (
            f"Study sent: **{file_name}** ({runs} run{'s' if runs != 1 else ''}); Open study or `diagnose --resume` continues it."
        )

    def open_study(self, name: str, content: bytes) -> None:
        """A study from the browser: checked whole before anything of the session changes."""
        s = self.session
        loop = s.loop
        source = name or "study.json"
        try:
            if loop.study is not None and loop.study_open:
                raise InputError(f"this server continues the study {loop.study.name} (serve --study): it is already open", file=source)
            study = Study.parse(parse_json_object(content, source, "study"), source, loop.catalog)
            shown, sha256 = shown_campaign(s)
            study.rings_added_on(sha256, shown)
            chain, steps = study.effects(loop.catalog), list(study.steps)
        except InputError as error:
            self.status.content = f"**Not opened** — {error.line()}\n\nThe session keeps what it had."
            return
        # The study continues here as serve --study's does (physics.py): its chain, its history.
        loop.previous, loop.chain, loop.steps = study, chain, steps
        loop.refitted, loop.diagnosed, loop.study_open = None, False, True
        loop.panel.show_history(steps)
        reached = " + ".join(effect_label(e) for e in chain) or "the baseline alone"
        runs = len(study.runs)
        self.status.content = (
            f"Opened study **{source}**: {runs} run{'s' if runs != 1 else ''}; the model it reached: **{reached}**; verdict "
            f"of its last run: **{study.verdict}**. Diagnose continues from that model; Export report includes it."
        )
