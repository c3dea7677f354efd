"""Reports and studies (issue 15, item 7): the exported report of a diagnosed campaign is one file
that fetches nothing, and Debian's chromium draws its polar plot, map, tables and history; the
command line refuses bad input in one line (exit 2) and writes nothing; a teaching scenario's
report names no hidden effect unless asked to reveal; in the explorer, Export report sends the
report as a download and Open study loads a study (a bad file changes nothing).

The diagnosed campaign is test_app_study's small twin campaign (40 rings, a hidden 22/rev B-axis
error): its diagnosis takes seconds.
"""

from __future__ import annotations

import io
import json
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
from command_line import run_cli
from fake_browser import open_session, wait_for
from test_app_study import B22, SMALL
from test_teaching import TEACHING, named

from ph_explorer import twin
from ph_explorer.app.dataset import dataset_for
from ph_explorer.app.server import ExplorerApp
from ph_explorer.campaign import orientation_label
from ph_explorer.diagnosis import Diagnosis, diagnose
from ph_explorer.diagnosis.study import Study, study_campaign
from ph_explorer.effects import DEFAULT_CATALOG, effect_label
from ph_explorer.figures.html_report import report_html
from ph_explorer.io import campaign_sha256, file_sha256, read_campaign, write_campaign, write_json_object
from ph_explorer.models.folder import CARD_FORMAT, CARD_NAME, campaign_models
from ph_explorer.models.trilinear import TrilinearModel
from ph_explorer.twin import scenario_from_dict, simulate

CHROMIUM = "/usr/bin/chromium"
ARGS = ["--no-sandbox", "--enable-unsafe-swiftshader", "--disable-background-networking", "--disable-gpu"]


@pytest.fixture(scope="module")
def small_csv(tmp_path_factory) -> Path:
    return write_campaign(simulate(scenario_from_dict(SMALL)), tmp_path_factory.mktemp("report") / "small.csv")


@pytest.fixture(scope="module")
def diagnosed(small_csv: Path):
    """The small campaign, its models, its diagnosis and the study `diagnose --save` would write."""
    campaign = read_campaign(small_csv)
    result = diagnose(campaign)
    assert result.verdict == "missing" and [effect_label(e) for e in result.chain] == [B22]
    study = Study.of_run(result, result.chain, study_campaign(small_csv.name, file_sha256(small_csv), campaign), "trilinear").to_json()
    models, train, _ = campaign_models(campaign, None)
    return campaign, models, train, result, study


def as_study(study: dict, source: str = "study") -> Study:
    """A study's JSON as the report reads it (checked whole)."""
    return Study.parse(study, source, DEFAULT_CATALOG)


@pytest.fixture(scope="module")
def report(diagnosed) -> str:
    campaign, models, train, result, study = diagnosed
    return report_html(campaign, models, train, DEFAULT_CATALOG, [(43.0, 90.0), (30.0, 0.0)], as_study(study), result, reveal=True)


def external_references(page: str) -> list[str]:
    """Everything in an HTML page that would make a browser fetch: a URL scheme, a src, an href or a
    CSS url() that is not a data: URI or a fragment, an @import, a script."""
    found = re.findall(r"(?:https?|ftp|file):", page)
    found += [m for m in re.findall(r"""(?:src|href)\s*=\s*["']?([^"'\s>]+)""", page) if not m.startswith(("data:", "#"))]
    found += [m for m in re.findall(r"url\(\s*['\"]?([^)'\"]+)", page) if not m.startswith(("data:", "#"))]
    found += re.findall(r"@import|<script|<link|<iframe|<object|<embed", page, flags=re.IGNORECASE)
    return found


def test_the_check_would_catch_an_external_reference() -> None:
    assert external_references('<img src="https://example.org/a.png">')
    assert external_references('<img src="a.png">') == ["a.png"]
    assert external_references("<style>@import 'x.css'</style>")
    assert not external_references('<img src="data:image/png;base64,AAAA"><rect fill="url(#viridis)"/>')


def test_the_report_is_one_file_with_the_campaign_its_figures_and_its_diagnosis(report: str, diagnosed) -> None:
    campaign, _, _, result, study = diagnosed
    assert report.startswith("<!DOCTYPE html>") and report.rstrip().endswith("</html>")
    assert external_references(report) == []
    # The campaign: its size, repetitions, points, geometry and noise floor.
    assert f"{campaign.n_orientations} (" in report and f"<td>{campaign.n_repetitions}</td>" in report
    assert f"<td>{campaign.n_points}</td>" in report and "bore diameter 20 mm" in report
    assert f"{result.noise_floor_um['mean']:.4f} um vs the repetition mean" in report
    # Figures inline: the two maps, a polar plot and Tables 1-3 per chosen orientation.
    assert report.count('aria-label="error map') == 2 and report.count('aria-label="polar plot') == 2
    assert "A43 B90 — measured, held out of training (check ring)" in report and "A30 B0 — measured, a training ring" in report
    assert report.count("Table 3 — mean absolute prediction error") == 2
    # The diagnosis: verdict, the fitted effect +- U, each step with its MAE and floor, nested figures, failing rings.
    assert "Verdict: missing" in report
    entry = study["chain"][0]
    assert DEFAULT_CATALOG["b_axis_cyclic"].parameters_text(entry["params"], entry["params_u"]) in report
    for step in study["steps"]:
        assert f"<td>{step['mae_um']['mean']:.3f}</td><td>{step['noise_floor_um']['mean']:.3f}</td>" in report
    assert f"<td>{study['nested_after']['after_um']['mean']:.3f}</td>" in report
    worst = result.failing_rings()[0]
    assert f"{len(result.failing_rings())} of {campaign.n_orientations} rings exceed their noise" in report
    assert f"<td>A{worst.a_deg:g} B{worst.b_deg:g}</td>" in report
    # Revealed on request: the hidden effect by name with its truth.
    assert "Revealed" in report and "B-axis cyclic angular error (b_axis_cyclic)" in report and "amplitude 2 arcsec" in report


def test_a_teaching_report_names_no_hidden_effect_unless_revealed(diagnosed) -> None:
    campaign, models, train, result, study = diagnosed
    hidden = report_html(campaign, models, train, DEFAULT_CATALOG, None, as_study(study), result)
    # The small campaign hides head_3's effect: the shipped scenario's checker applies.
    assert campaign.scenario["hidden"] == twin.load_scenario("head_3").hidden_ids
    assert named(hidden, "head_3") == [], named(hidden, "head_3")
    assert "effect A" in hidden and "22 cycles/rev" in hidden  # what was found stays, by letter
    # Words that are not an effect named stay words: touch noise (id "noise"), a parameter (gravity's lobing).
    assert "within noise" in hidden and not re.search(r"(within|noise alone|noise floor).{0,3}effect [A-Z]", hidden)
    assert not re.search(r"effect [A-Z] [-\d.]+ (\+-|um)", hidden)
    # No orientation named: the ring that fails worst, then the first check ring.
    worst, first_check = result.failing_rings()[0], campaign.orientations[campaign.holdout_mask()][0]
    headings = re.findall(r"<h3>(A[-\d.]+ B[-\d.]+)</h3>", hidden)
    assert headings == [f"A{worst.a_deg:g} B{worst.b_deg:g}", f"A{first_check[0]:g} B{first_check[1]:g}"]
    assert "Revealed" not in hidden
    revealed = report_html(campaign, models, train, DEFAULT_CATALOG, None, as_study(study), result, reveal=True)
    assert set(named(revealed, "head_3")) >= {"b_axis_cyclic", "cyclic"}


@pytest.mark.parametrize("name", TEACHING)
def test_no_shipped_teaching_scenario_is_spoiled_by_its_report(name: str) -> None:
    loaded = twin.load_scenario(name)
    campaign = twin.simulate(loaded, loaded.seed)
    models, train, _ = campaign_models(campaign, None)
    page = report_html(campaign, models, train, DEFAULT_CATALOG)
    assert named(page, name) == [], named(page, name)
    assert "not been diagnosed" in page


# -- the command line ---------------------------------------------------------------------------------


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return run_cli("report", *args)


def test_the_command_diagnoses_and_writes_one_file(small_csv: Path, tmp_path: Path) -> None:
    out = tmp_path / "report.html"
    result = run("--data", str(small_csv), "--orientations", "43:90,12:34", "--out", str(out))
    assert result.returncode == 0, result.stderr
    page = out.read_text(encoding="utf-8")
    assert external_references(page) == [] and "Verdict: missing" in page
    assert "A12 B34 — not measured: model **predictions** only" not in page  # markdown rendered, not shown raw
    assert "A12 B34 — not measured: model <strong>predictions</strong> only" in page
    assert "Where it fails" in page and "exceed their noise under the baseline, worst first" in page
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.html"]


def test_with_a_model_folder_the_command_loads_it_once(small_csv: Path, tmp_path: Path, monkeypatch) -> None:
    """--model: the folder's models are the diagnosis's baseline and the report's curves, read once."""
    folder = tmp_path / "model"
    campaign = read_campaign(small_csv)
    TrilinearModel().fit(campaign, ~campaign.holdout_mask()).save(folder)
    (folder / CARD_NAME).write_text(json.dumps({"format": CARD_FORMAT, "holdout": []}), encoding="utf-8")
    loads = []
    original = TrilinearModel.load.__func__
    monkeypatch.setattr(TrilinearModel, "load", classmethod(lambda cls, directory: loads.append(directory) or original(cls, directory)))
    result = run("--data", str(small_csv), "--model", str(folder), "--out", str(tmp_path / "report.html"))
    assert result.returncode == 0, result.stderr
    assert loads == [folder] and "Verdict: missing" in (tmp_path / "report.html").read_text(encoding="utf-8")


def test_the_command_reports_a_study_of_a_scenario_without_diagnosing(diagnosed, tmp_path: Path) -> None:
    """A study of the file simulate --out writes is a study of --scenario (the same bytes)."""
    campaign, _, _, result, study = diagnosed
    loaded = twin.load_scenario("head_3")
    scenario_study = dict(study, campaign=study_campaign("head_3.csv", campaign_sha256(twin.simulate(loaded, loaded.seed)), campaign))
    path = tmp_path / "study.json"
    write_json_object(path, scenario_study)
    out = tmp_path / "head_3.html"
    result = run("--scenario", "head_3", "--study", str(path), "--out", str(out))
    assert result.returncode == 0, result.stderr
    page = out.read_text(encoding="utf-8")
    assert "scenario head_3" in page and "Verdict: missing" in page and named(page, "head_3") == []
    # The study records its diagnosis whole: the rings that failed are named without diagnosing again.
    rings = Diagnosis.from_json(study["diagnosis"]).failing_rings()
    assert rings and f"{len(rings)} of {campaign.n_orientations} rings exceed their noise" in page
    assert orientation_label(rings[0].a_deg, rings[0].b_deg) in page
    # ... and its record maps each ring's test and draws the worst ring first, as a report diagnosed here does.
    assert "out-of-sample MAE / its floor" in page
    assert page.index(f"<h3>{orientation_label(rings[0].a_deg, rings[0].b_deg)}</h3>") == page.index("<h3>A")


def bad_inputs(small_csv: Path, tmp_path: Path) -> list[tuple[list[str], str]]:
    other = write_campaign(simulate(scenario_from_dict(dict(SMALL, seed=6))), tmp_path / "other.csv")
    not_json = tmp_path / "notes.json"
    not_json.write_bytes(b"\xff\xfe not text")
    other_study = tmp_path / "other_study.json"
    write_json_object(
        other_study,
        {
            "format": "ph-explorer study 1",
            "campaign": {"sha256": file_sha256(other)},
            "baseline": "trilinear",
            "data_part": "trilinear",
            "chain": [],
            "runs": [],
        },
    )
    unknown = tmp_path / "unknown_effect.json"
    write_json_object(
        unknown,
        {
            "format": "ph-explorer study 1",
            "campaign": {"sha256": file_sha256(small_csv)},
            "baseline": "trilinear",
            "data_part": "trilinear",
            "chain": [{"effect": "wobble", "settings": {}}],
            "runs": [],
        },
    )
    (tmp_path / "a_folder").mkdir()
    data = ["--data", str(small_csv)]
    return [
        ([], "option --data: give one campaign"),
        ([*data, "--scenario", "head_3"], "option --data: give one campaign"),
        (["--data", str(tmp_path / "missing.csv")], "missing.csv: no such file"),
        (["--scenario", "no_such_scenario"], "no_such_scenario"),
        (["--scenario", "head_3", "--bore-diameter-mm", "30"], "option --bore-diameter-mm: applies to a campaign file (--data)"),
        ([*data, "--orientations", "43;90"], "option --orientations: '43;90' is not an orientation"),
        ([*data, "--orientations", "200:0"], "option --orientations: 200:0 is out of range"),
        ([*data, "--study", str(not_json)], "notes.json: not a study: not UTF-8 text"),
        ([*data, "--study", str(other_study)], "other_study.json: the study was made on another campaign"),
        ([*data, "--study", str(unknown)], "unknown_effect.json, column chain[0]: effect 'wobble' is not a candidate"),
        ([*data, "--model", str(tmp_path / "no_model")], "no_model: model folder not found"),
    ]


def test_bad_input_is_one_line_exit_2_and_no_file(small_csv: Path, tmp_path: Path) -> None:
    out = tmp_path / "out" / "report.html"
    out.parent.mkdir()
    for args, expected in bad_inputs(small_csv, tmp_path):
        result = run(*args, "--out", str(out))
        lines = result.stderr.strip().splitlines()
        assert result.returncode == 2 and len(lines) == 1 and expected in lines[0], (args, result.stderr)
        assert list(out.parent.iterdir()) == [], args  # nothing written, not even a temp file
    for target, expected in ((tmp_path / "a_folder", "is a folder"), (tmp_path / "nowhere" / "r.html", "no such folder")):
        result = run("--data", str(small_csv), "--out", str(target))
        assert result.returncode == 2 and len(result.stderr.strip().splitlines()) == 1 and expected in result.stderr, result.stderr
    assert not (tmp_path / "nowhere").exists()


# -- in Debian's chromium ----------------------------------------------------------------------------


def drawn_colours(png: bytes) -> tuple[int, float]:
    """How many distinct colours cover at least 0.2 % of a screenshot (coarsely binned), and the
    share of pixels that are not white: a drawn figure has several and a fair share; a blank one neither."""
    from PIL import Image  # pillow comes with matplotlib, a test dependency

    rgb = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=int)
    binned = (rgb // 32).reshape(-1, 3)
    _, counts = np.unique(binned, axis=0, return_counts=True)
    return int((counts >= 0.002 * len(binned)).sum()), float((rgb.min(axis=-1) < 235).mean())


@pytest.mark.browser
@pytest.mark.slow
def test_chromium_draws_the_polar_plot_the_map_the_tables_and_the_history(report: str, tmp_path: Path) -> None:
    if not Path(CHROMIUM).exists():
        pytest.skip("Debian's chromium is not installed (/usr/bin/chromium); apt-get install chromium")
    from playwright.sync_api import sync_playwright

    path = tmp_path / "report.html"
    path.write_text(report, encoding="utf-8")
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        page = browser.new_page(viewport={"width": 1440, "height": 900})
        requests: list[str] = []
        page.on("request", lambda request: requests.append(request.url))
        errors: list[str] = []
        page.on("pageerror", lambda error: errors.append(str(error)))
        page.goto(path.as_uri())
        page.wait_for_load_state("load")
        assert requests == [path.as_uri()] and errors == []  # the file alone: nothing else fetched
        figures = {
            "polar plot": ("#polar-1 svg", 4, 0.04),  # grey repetitions, black mean, orange model, scale circles
            "error map": ("#map-1 svg", 6, 0.1),  # viridis markers and colour bar
            "tables": ("#tables-1", 2, 0.03),  # Tables 1-3 with their headings
            "history": ("#history-chart svg", 4, 0.04),  # blue and orange lines, grid, frame
        }
        for what, (selector, colours, share) in figures.items():
            element = page.locator(selector).first
            element.scroll_into_view_if_needed()
            box = element.bounding_box()
            assert box is not None and box["width"] > 250 and box["height"] > 60, (what, box)
            found, inked = drawn_colours(element.screenshot(path=str(tmp_path / f"report_{what.replace(' ', '_')}.png")))
            assert found >= colours and inked >= share, (what, found, inked)
        browser.close()


# -- in the explorer ----------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def app(small_csv: Path):
    campaign = read_campaign(small_csv)
    explorer = ExplorerApp(dataset_for(campaign, f"campaign {small_csv.name}", None), port=0)
    yield explorer
    explorer.stop()


def test_open_study_loads_it_and_export_report_sends_it(app, diagnosed, tmp_path: Path) -> None:
    _, _, _, _, study = diagnosed
    fake, s = open_session(app)
    try:
        # Before a diagnosis or a study: a report without a diagnosis, and the status says how to get one.
        fake.click("Export report")
        page = fake.download("report_small_b22.html", timeout=120).decode("utf-8")
        assert "not been diagnosed" in page and "Verdict" not in page
        assert wait_for(lambda: "not diagnosed yet" in s.report_panel.status.content)
        # Bad bytes: one line, the session unchanged.
        fake.upload("Open study", "notes.json", b"\xff\xfe not a study")
        assert wait_for(lambda: "Not opened" in s.report_panel.status.content)
        assert "notes.json: not a study: not UTF-8 text" in s.report_panel.status.content
        assert s.loop.steps == [] and not s.loop.study_open
        other = dict(study, campaign=dict(study["campaign"], sha256="0" * 64))
        fake.upload("Open study", "other.json", json.dumps(other).encode())
        assert wait_for(lambda: "other.json: the study was made on" in s.report_panel.status.content)
        assert s.loop.steps == [] and not s.loop.study_open
        # A study of this campaign: its history and the model it reached.
        fake.upload("Open study", "study.json", json.dumps(study).encode())
        assert wait_for(lambda: "Opened study" in s.report_panel.status.content), s.report_panel.status.content
        assert [effect_label(e) for e in s.loop.chain] == [B22] and s.loop.study_open
        assert [step.mae_um["mean"] for step in s.loop.steps] == pytest.approx([step["mae_um"]["mean"] for step in study["steps"]])
        assert s.physics.history.visible
        # Export report: the same HTML the core makes, as a download, with the study's diagnosis.
        fake.click("Export report")
        assert wait_for(lambda: len(fake.downloaded()) == 2, timeout=120)
        page = fake.download("report_small_b22.html", timeout=120).decode("utf-8")
        assert wait_for(lambda: "with its diagnosis" in s.report_panel.status.content)
        assert external_references(page) == [] and "Verdict: missing" in page
        assert page.count('aria-label="polar plot') >= 1 and 'aria-label="error map' in page
        # The orientation on screen comes first (here not measured: the models' predictions).
        a, b = s.orientation
        assert re.findall(r"<h3>(A[-\d.]+ B[-\d.]+)</h3>", page)[0] == f"A{a:g} B{b:g}"
        assert s.dataset.campaign.index_of(a, b) is None and f"A{a:g} B{b:g} — not measured" in page
        for step in study["steps"]:
            assert f"<td>{step['mae_um']['mean']:.3f}</td>" in page
        assert named(page, "head_3") == []  # the explorer's report is a teaching report too unless asked
        # Download study: the opened study continued, as a file that Open study and --resume read.
        fake.click("Download study")
        assert wait_for(lambda: "Study sent" in s.report_panel.status.content, timeout=120)
        saved = json.loads(fake.download("study_small_b22.json", timeout=120).decode("utf-8"))
        assert as_study(saved, "study_small_b22.json").to_json() == saved
        assert saved["campaign"] == study["campaign"] and len(saved["runs"]) == len(study["runs"])
        assert [step["mae_um"]["mean"] for step in saved["steps"]] == pytest.approx([step["mae_um"]["mean"] for step in study["steps"]])
    finally:
        s.wait(timeout=120)
        fake.close()


def test_the_report_after_a_refit_is_the_session(app) -> None:
    """Issue 31, item 7: Diagnose, tick the found effect, Refit, Export report: the report holds the
    model as refitted (not "the baseline alone"), every step of the history, the candidates ranked
    and a signature plot; the found effect is named only once the browser has revealed it."""
    fake, s = open_session(app)
    try:
        fake.click("Diagnose")
        assert wait_for(lambda: s.loop.diagnosis is not None, timeout=300)
        s.wait(timeout=300)
        found = s.loop.diagnosis.found[0].effect
        s.physics.effects[found].value = True
        fake.click("Refit the hybrid")
        assert wait_for(lambda: len(s.loop.steps) == 2, timeout=300)
        s.wait(timeout=120)
        fake.click("Export report")
        page = fake.download("report_small_b22.html", timeout=120).decode("utf-8")
        assert "the model is the baseline" not in page and "Effects in the model, fitted parameters" in page
        history = page[page.index('id="history"') :]
        for step in s.loop.steps:  # every step of the session's history, in its table
            assert f"<td>{step.mae_um['mean']:.3f}</td>" in history
        assert history.count("</tspan></text>") >= 2 and ">baseline</tspan>" in history  # steps named on the chart
        assert "Candidate effects, best first" in page and 'id="signature-chart"' in page and "signature plot" in page
        assert named(page, "head_3") == []  # a teaching campaign, not revealed: "effect A"
        fake.click("Reveal the hidden effect")
        assert wait_for(lambda: s.loop.revealed, timeout=60)
        fake.click("Export report")
        assert wait_for(lambda: len(fake.downloaded()) == 2, timeout=120)
        page = fake.download("report_small_b22.html", timeout=120).decode("utf-8")
        assert f"{DEFAULT_CATALOG[found].name} ({found})" in page and f"+ {found}" in page
    finally:
        s.wait(timeout=120)
        fake.close()


def test_download_study_before_anything_says_what_to_do_first(app) -> None:
    fake, s = open_session(app)
    try:
        fake.click("Download study")
        assert wait_for(lambda: "Nothing to download" in s.report_panel.status.content, timeout=60)
        assert not fake.downloaded()
    finally:
        s.wait(timeout=60)
        fake.close()


@pytest.mark.browser
@pytest.mark.slow
def test_in_chromium_open_study_then_export_report_downloads_the_file(app, diagnosed, tmp_path: Path) -> None:
    """The same through viser's own web client: the upload button's file chooser, then a real download."""
    if not Path(CHROMIUM).exists():
        pytest.skip("Debian's chromium is not installed (/usr/bin/chromium); apt-get install chromium")
    from playwright.sync_api import sync_playwright

    _, _, _, _, study = diagnosed
    study_path = tmp_path / "study.json"
    write_json_object(study_path, study)
    before = set(app.sessions)
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        page = browser.new_page(viewport={"width": 1440, "height": 900}, accept_downloads=True)
        page.goto(app.url)
        assert wait_for(lambda: set(app.sessions) - before, timeout=60)
        s = app.sessions[min(set(app.sessions) - before)]
        page.get_by_role("tab", name="Data").click()
        with page.expect_file_chooser() as chooser:
            page.get_by_role("button", name="Open study").click()
        chooser.value.set_files(str(study_path))
        assert wait_for(lambda: "Opened study" in s.report_panel.status.content, timeout=60), s.report_panel.status.content
        with page.expect_download(timeout=120_000) as download:
            page.get_by_role("button", name="Export report").click()
        saved = tmp_path / download.value.suggested_filename
        download.value.save_as(str(saved))
        text = saved.read_text(encoding="utf-8")
        assert saved.name == "report_small_b22.html" and "Verdict: missing" in text and external_references(text) == []
        browser.close()


def test_a_study_of_format_1_still_reads_and_reports_its_verdict(diagnosed) -> None:
    """A study written before the diagnosis record: its verdict beside its runs, no record."""
    campaign, models, train, _, study = diagnosed
    old = {k: v for k, v in study.items() if k != "diagnosis"} | {"format": "ph-explorer study 1", "verdict": "missing"}
    old["runs"] = [{k: v for k, v in run.items() if k != "verdict"} for run in study["runs"]]
    read = as_study(old, "old.json")
    assert read.diagnosis is None and read.verdict == "missing" and [link.effect for link in read.chain] == ["b_axis_cyclic"]
    page = report_html(campaign, models, train, DEFAULT_CATALOG, None, read)
    assert "Verdict: missing" in page and "records no diagnosis of this version" in page
