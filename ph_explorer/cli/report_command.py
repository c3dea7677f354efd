"""`ph-explorer report`: a campaign and its diagnosis as one self-contained HTML file (ph_explorer/figures/html_report.py).

The diagnosis is a study's (`--study`, made by `diagnose --save` or the explorer), else it is run
here as `ph-explorer diagnose` runs it. Every input is checked before the diagnosis; the file is
written atomically, so a failure leaves no half-written report.
"""

from __future__ import annotations

import datetime
from pathlib import Path

from rich.progress import Progress

from ph_explorer.cli.uncertainty_command import checked_orientations
from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.errors import InputError
from ph_explorer.io import campaign_sha256, checked_output_file, file_sha256
from ph_explorer.io.writer import atomic_write
from ph_explorer.models.lattice_need import read_lattice_campaign


def report_command(
    out: Path,
    data: Path | None = None,
    scenario: str | None = None,
    model: Path | None = None,
    study: Path | None = None,
    orientations: str | None = None,
    reveal: bool = False,
    geometry: dict[str, float] | None = None,
) -> int:
    """Write the report of --data or --scenario to --out; diagnose first when no --study is given."""
    # torch-bound (the diagnosis, the models): imported when the command runs, as diagnose does.
    from ph_explorer import twin
    from ph_explorer.cli.simulate_command import scenario_of
    from ph_explorer.diagnosis.campaign_file import diagnose_campaign
    from ph_explorer.diagnosis.study import Study
    from ph_explorer.figures.html_report import diagnosed_report_html, report_html
    from ph_explorer.models.folder import campaign_models, load_models

    if (data is None) == (scenario is None):
        raise InputError("give one campaign: --data FILE.csv or --scenario NAME", option="--data")
    if scenario is not None and geometry:
        # A scenario carries its own geometry: an option that changed nothing would mislead.
        raise InputError(
            "applies to a campaign file (--data); a scenario has its own geometry", option="--" + sorted(geometry)[0].replace("_", "-")
        )
    out = checked_output_file(out, "--out", "the report", "report.html")
    chosen = checked_orientations(orientations) if orientations is not None else None
    if data is not None:
        campaign = read_lattice_campaign(data, geometry)
        name, sha256 = Path(data).name, file_sha256(Path(data))
    else:
        loaded = scenario_of(str(scenario))
        campaign = twin.simulate(loaded, loaded.seed)
        # The bytes simulate --out writes: a study of that file is a study of this campaign.
        name, sha256 = f"scenario {loaded.name}", campaign_sha256(campaign)
    campaign.source = name
    previous = None
    if study is not None:  # checked whole: every effect it names is one the report can describe
        previous = Study.load(Path(study), DEFAULT_CATALOG)
        previous.rings_added_on(sha256, name)
    created = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    if previous is not None:
        models, train, _ = campaign_models(campaign, model)
        # The study's last run was made on these very bytes (rings_added_on): its record maps each
        # ring's test and names the ring that fails worst, as a report diagnosed here does.
        diagnosis = previous.diagnosis
        text = report_html(campaign, models, train, DEFAULT_CATALOG, chosen, previous, diagnosis, reveal=reveal, created=created)
    else:
        # As `ph-explorer diagnose` runs it: the loaded model is the baseline, the trilinear data part;
        # the folder is loaded once, for the diagnosis and the report's figures.
        loaded = load_models(Path(model)) if model is not None else None
        with Progress(transient=True) as bar:
            task = bar.add_task("diagnosing: scanning candidate effects", total=None)
            result = diagnose_campaign(
                campaign,
                DEFAULT_CATALOG,
                model=loaded,
                progress=lambda activity: bar.update(task, description=f"diagnosing: {activity}"),
            )
        text = diagnosed_report_html(
            campaign, result, name, sha256, model, orientations=chosen, reveal=reveal, created=created, loaded=loaded
        )
    try:
        atomic_write([(out, text)])
    except OSError as error:
        raise InputError(f"cannot write the report: {error.strerror or error}", file=str(out), option="--out") from None
    print(f"Report written to {out} ({len(text) // 1024} KiB, one file).")
    return 0
