"""The explorer without a browser: viser in-process on port 0, browsers faked by websocket clients.

A fake browser (tests/fake_browser.py) connects with viser's protocol; the test then moves that
browser's sliders and clicks its buttons (as messages from the browser) or sets GUI values on its
session (as a script would), and asserts on its scene handles and panel contents.
"""

from __future__ import annotations

import dataclasses
import threading

import numpy as np
import pytest
from fake_browser import FakeBrowser, camera_message, open_session, wait_for
from synthetic import lobing_campaign
from viser.transforms import SO3

from ph_explorer.app.dataset import Dataset, dataset_for
from ph_explorer.app.panels import NO_CHOICE
from ph_explorer.app.render_queue import RenderState
from ph_explorer.app.scene import joint_wxyz
from ph_explorer.app.server import ExplorerApp, build_server
from ph_explorer.app.session import Session
from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.geometry import A_LIMIT_DEG, head_rotation, rot_z, stylus_direction
from ph_explorer.io import write_campaign
from ph_explorer.paper.tables import RONT_HEADER


def rotation_of(wxyz: np.ndarray) -> np.ndarray:
    """The rotation matrix of a viser frame's (w, x, y, z) quaternion."""
    return SO3(np.asarray(wxyz, dtype=float)).as_matrix()


@pytest.fixture(scope="module")
def dataset() -> Dataset:
    campaign = lobing_campaign(seed=3, extra_orientations=((43.0, 90.0), (15.0, -20.0)))
    return dataset_for(campaign, "synthetic test campaign", None)


@pytest.fixture(scope="module")
def app(dataset: Dataset):
    explorer = ExplorerApp(dataset, host="127.0.0.1", port=0)
    yield explorer
    explorer.stop()


@pytest.fixture()
def opened(app: ExplorerApp):
    fake, session = open_session(app)
    yield fake, session
    session.wait(timeout=120)  # its jobs end while the browser still listens
    fake.close()


@pytest.fixture()
def browser(opened) -> Session:
    return opened[1]


def click(fake: FakeBrowser, session: Session, label: str, timeout: float = 120.0) -> None:
    """The user clicks a button that starts a job: the browser's message, then that job to its end."""
    before = len(session.jobs)
    fake.click(label)
    assert wait_for(lambda: len(session.jobs) > before), f"{label!r} started no job"
    session.wait(timeout=timeout)


def test_rotations_match_the_geometry_conventions() -> None:
    for a, b in [(0, 0), (15, -20), (43, 90), (75, 40), (110, -170), (-30, 60)]:
        b_turn, a_turn, head = (rotation_of(np.array(q)) for q in joint_wxyz(a, b))
        np.testing.assert_allclose(head, head_rotation(a, b), atol=1e-12)
        np.testing.assert_allclose(b_turn @ a_turn, head_rotation(a, b), atol=1e-12)
        np.testing.assert_allclose(b_turn, rot_z(b), atol=1e-12)


def test_binds_localhost_and_serves_the_page(app: ExplorerApp) -> None:
    import urllib.request

    assert app.host == "127.0.0.1" and app.port > 0
    html = urllib.request.urlopen(app.url, timeout=10).read().decode()
    assert "<html" in html.lower()


def test_a_browser_is_lit_without_an_environment_map_to_prefilter(opened) -> None:
    """No HDR image for the browser to prefilter on load (without a GPU that stalled the page ~4 s);
    a sky-and-ground light instead (ph_explorer/app/loading.py)."""
    from ph_explorer.app.loading import HEMISPHERE_LIGHT

    fake, _ = opened
    assert wait_for(lambda: "HemisphereLightMessage" in fake.last and "EnvironmentMapMessage" in fake.last)
    assert fake.last["EnvironmentMapMessage"]["hdri_data"] is None
    light = fake.last["HemisphereLightMessage"]["props"]
    assert light["intensity"] == HEMISPHERE_LIGHT["intensity"] and tuple(light["ground_color"]) == HEMISPHERE_LIGHT["ground_color"]


def test_sliders_turn_the_head_and_move_the_ring_and_curves(browser) -> None:
    s = browser
    s.controls.a.value = 43.0
    s.controls.b.value = 90.0
    # Nested joint frames: B about z, A about x, composing to the head rotation.
    r = rotation_of(s.head.b_frame.wxyz) @ rotation_of(s.head.a_frame.wxyz)
    np.testing.assert_allclose(r, head_rotation(43.0, 90.0), atol=1e-9)
    ball = r @ np.array([0.0, 0.0, -s.dataset.campaign.geometry.pivot_to_ball_mm])
    np.testing.assert_allclose(ball / np.linalg.norm(ball), stylus_direction(43.0, 90.0), atol=1e-9)
    # The ring's axis lies along the stylus, its plane at the ball's depth.
    axis = -rotation_of(s.ring.frame.wxyz)[:, 2]
    np.testing.assert_allclose(axis, stylus_direction(43.0, 90.0), atol=1e-9)
    np.testing.assert_allclose(
        s.ring.frame.position, s.dataset.campaign.geometry.axial_distance_mm * stylus_direction(43.0, 90.0), atol=1e-6
    )
    # A43 B90 was measured: the measured mean and the trilinear curve are drawn, radius = base + m dev.
    view = s.dataset.view(43.0, 90.0)
    assert view.measured and s.ring.curves["measured"].visible and s.ring.curves["trilinear"].visible
    radius = np.linalg.norm(s.ring.points["measured"][:, :2], axis=1)
    expected = s.ring.scale.base_mm + s.controls.magnification.value * 1e-3 * view.curves["measured"]
    np.testing.assert_allclose(radius, expected, rtol=1e-9)
    drawn = np.asarray(s.ring.curves["measured"].points)
    np.testing.assert_allclose(drawn[:, 0, :2], s.ring.points["measured"][:, :2], atol=1e-4)
    s.go_to(45.0, -20.0)
    before = np.asarray(s.ring.curves["measured"].points).copy()
    s.controls.a.value = 75.0  # A75 B-20 is measured too: another curve
    assert s.view.measured
    assert not np.allclose(np.asarray(s.ring.curves["measured"].points), before, atol=1e-3)


def on_screen(points, position, look_at, height_px: float = 900.0) -> np.ndarray:
    """(x, y) px from the canvas's centre (y up) of world points through a camera with z up and the
    app's field of view (CAMERA_FOV_DEG, vertical), on a canvas height_px high; NaN behind it."""
    from ph_explorer.app.scene import CAMERA_FOV_DEG

    forward = (np.asarray(look_at) - position) / np.linalg.norm(np.asarray(look_at) - position)
    right = np.cross(forward, (0.0, 0.0, 1.0))
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    rel = np.atleast_2d(points) - position
    depth = rel @ forward
    focal = 0.5 * height_px / np.tan(np.radians(0.5 * CAMERA_FOV_DEG))
    xy = focal * np.stack([rel @ right, rel @ up], axis=1) / depth[:, None]
    xy[depth <= 0] = np.nan
    return xy


def test_ring_and_head_shows_the_whole_head_a_readable_ring_and_no_number_on_the_stylus(browser) -> None:
    """Issue 57, item 8: at any orientation and canvas (1440x900's 632 x 900 between the docked
    panels, 1280x720's, a wide one) the View 'ring + head' has every part of the head and the whole
    chart inside the canvas (the head was cut off at the top), the chart at least a seventh of the
    canvas's height across both ways (126 px at 1440x900, as large as the head leaves room for:
    136-226 px), and no point number within 20 px of the stylus (32 sat on it)."""
    from ph_explorer.app.scene import head_parts, head_points, ring_camera

    s = browser
    geometry = s.dataset.campaign.geometry
    # The stylus is drawn from the ball up to the probe's module: its top, in the A joint's frame.
    stylus_top = -max(
        p.mesh.bounds[1][2] for p in head_parts(geometry.pivot_to_ball_mm, geometry.ball_diameter_mm) if p.name == "B/A/stylus"
    )
    for a, b in ((0.0, 0.0), (15.0, -20.0), (43.0, 90.0), (75.0, 40.0), (90.0, -150.0), (A_LIMIT_DEG, 120.0)):
        s.go_to(a, b)
        centre, frame = np.asarray(s.ring.frame.position), SO3(np.asarray(s.ring.frame.wxyz, dtype=float))
        numbers = np.array([frame.apply(np.asarray(h.position)) for h in s.ring.labels]) + centre
        theta = np.radians(np.arange(0.0, 360.0, 5.0))
        e1, e2 = frame.as_matrix()[:, 0], frame.as_matrix()[:, 1]
        chart = centre + s.ring.extent_mm * (np.cos(theta)[:, None] * e1 + np.sin(theta)[:, None] * e2)
        head = head_points(a, b, geometry.pivot_to_ball_mm, geometry.ball_diameter_mm)
        for width, height in ((632, 900), (472, 720), (800, 600)):
            camera = ring_camera(a, b, geometry, extent_mm=s.ring.extent_mm, aspect=width / height)
            half = 0.5 * np.array([width, height])
            for what, points in (("head", head), ("chart", chart)):
                xy = on_screen(points, *camera, height)
                assert np.all(np.abs(xy) <= half), (a, b, width, what, np.nanmax(np.abs(xy) / half, axis=0))
            xy = on_screen(chart, *camera, height)
            assert np.min(xy.max(axis=0) - xy.min(axis=0)) >= height / 7.0, (a, b, width, xy.max(axis=0) - xy.min(axis=0))
            if width == 632:  # the point numbers clear of the stylus at 1440x900
                p0, p1 = on_screen([centre, stylus_top * stylus_direction(a, b)], *camera, height)
                xy = on_screen(numbers, *camera, height)
                t = np.clip((xy - p0) @ (p1 - p0) / np.dot(p1 - p0, p1 - p0), 0.0, 1.0)
                clear = np.linalg.norm(xy - (p0 + t[:, None] * (p1 - p0)), axis=1)
                assert clear.min() > 20.0, (a, b, dict(zip((h.text for h in s.ring.labels), clear.round())))


def test_the_camera_follows_the_ring_in_the_chosen_view(browser) -> None:
    from ph_explorer.app.scene import CAMERA_FOV_DEG, axis_camera, ring_camera

    s = browser
    geometry = s.dataset.campaign.geometry
    axial = geometry.axial_distance_mm
    s.go_to(43.0, 90.0)
    aspect = s.client.camera.aspect  # the fake browser's canvas: 800 x 600
    position, look_at = ring_camera(43.0, 90.0, geometry, extent_mm=s.ring.extent_mm, aspect=aspect)
    np.testing.assert_allclose(s.client.camera.position, position, atol=1e-6)
    np.testing.assert_allclose(s.client.camera.look_at, look_at, atol=1e-6)
    assert s.client.camera.fov == pytest.approx(np.radians(CAMERA_FOV_DEG))  # the field of view the View is framed for
    assert s.head.root.visible
    s.look("along the axis")
    s.go_to(75.0, 40.0)  # the following camera keeps the chosen view
    position, look_at, up = axis_camera(75.0, 40.0, axial, s.ring.extent_mm, aspect)
    np.testing.assert_allclose(s.client.camera.look_at, look_at, atol=1e-6)
    view = (look_at - s.client.camera.position) / np.linalg.norm(look_at - s.client.camera.position)
    np.testing.assert_allclose(view, stylus_direction(75.0, 40.0), atol=1e-9)  # square to the ring plane: undistorted
    # The head, between the camera and the ring, is hidden; the whole chart is inside the field
    # of view, centred, both ways for this canvas's aspect; the ring's e2 is up, so theta turns
    # counter-clockwise as on the panel's chart.
    centre = axial * stylus_direction(75.0, 40.0)
    distance = float(np.dot(centre - np.asarray(s.client.camera.position), view))
    assert distance > 0.0 and not s.head.root.visible
    np.testing.assert_allclose(look_at, centre, atol=1e-9)
    half = np.tan(np.radians(0.5 * CAMERA_FOV_DEG))  # vertical
    assert s.ring.extent_mm / distance < half * min(1.0, aspect)
    for narrow in (0.52, 0.66):  # a 1280x720 canvas between the panels, and narrower: still whole
        position, _, _ = axis_camera(75.0, 40.0, axial, s.ring.extent_mm, narrow)
        assert s.ring.extent_mm / np.linalg.norm(centre - position) < half * narrow
    np.testing.assert_allclose(s.client.camera.up_direction, rotation_of(s.ring.frame.wxyz)[:, 1], atol=1e-9)
    s.controls.follow.value = False
    s.go_to(15.0, -20.0)  # not following: the camera stays where the user put it
    np.testing.assert_allclose(s.client.camera.look_at, look_at, atol=1e-6)
    s.controls.follow.value = True
    s.look("ring + head")
    assert s.head.root.visible


def test_a_canvas_that_changes_shape_has_its_view_placed_again_and_an_orbit_keeps_its_camera(opened) -> None:
    """The canvas a browser reports changes shape (its panels dock after the first placement, its
    window is made narrow): the View is placed again for it, farther when narrower than the docked
    1440x900 canvas, so that the chart fits; an orbit (another position, the same shape) stays."""
    from ph_explorer.app.scene import ring_camera

    fake, s = opened
    s.go_to(43.0, 90.0)
    geometry = s.dataset.campaign.geometry
    fake.send(camera_message(400, 900))  # a narrow window
    position, look_at = ring_camera(43.0, 90.0, geometry, extent_mm=s.ring.extent_mm, aspect=400 / 900)
    # Both placed: viser's position setter moves look_at with it before the View sets its own, in
    # the handler's thread (the browser gets them in one atomic batch; this thread may look between).
    camera = s.client.camera
    placed = lambda: np.allclose(camera.position, position, atol=1e-6) and np.allclose(camera.look_at, look_at, atol=1e-6)  # noqa: E731
    assert wait_for(placed), (camera.position, position, camera.look_at, look_at)
    wide = ring_camera(43.0, 90.0, geometry, extent_mm=s.ring.extent_mm, aspect=800 / 600)[0]
    assert np.linalg.norm(position - look_at) > 1.05 * np.linalg.norm(wide - look_at)  # farther: the chart fits the narrow canvas
    orbit = (300.0, 50.0, 20.0)
    fake.send(camera_message(400, 900, position=orbit))
    assert wait_for(lambda: np.allclose(s.client.camera.position, orbit))
    s.camera.reframe()  # what the orbit's report calls: the same shape, nothing placed
    np.testing.assert_allclose(s.client.camera.position, orbit)


def test_a_view_click_is_not_undone_by_a_following_camera(browser, monkeypatch) -> None:
    """A follow that read the View before a click places the camera first; the click's View stays."""
    import ph_explorer.app.camera as camera
    from ph_explorer.app.scene import field_camera

    s, real = browser, camera.view_camera
    inside, release = threading.Event(), threading.Event()

    def held(view: str, *args: object):  # the follow waits, inside its placement, until released
        if threading.current_thread().name == "follow":
            inside.set()
            release.wait(10.0)
        return real(view, *args)

    monkeypatch.setattr(camera, "view_camera", held)
    follow = threading.Thread(target=s.camera.follow, args=(75.0, 40.0), name="follow")
    follow.start()
    assert inside.wait(10.0)
    click = threading.Thread(target=s.look, args=("whole field",))
    click.start()
    click.join(0.3)  # unserialised, the click would be placed here, then undone by the follow
    release.set()
    follow.join(10.0)
    click.join(10.0)
    assert s.camera.view == "whole field"
    np.testing.assert_allclose(s.client.camera.position, field_camera(s.client.camera.aspect)[0], atol=1e-6)


def test_magnification_scales_the_deviation_about_the_reference_circle(browser) -> None:
    s = browser
    s.go_to(15.0, -20.0)
    s.controls.magnification.value = 2000.0
    r1 = np.linalg.norm(s.ring.points["measured"][:, :2], axis=1) - s.ring.scale.base_mm
    s.controls.magnification.value = 20000.0
    r2 = np.linalg.norm(s.ring.points["measured"][:, :2], axis=1) - s.ring.scale.base_mm
    np.testing.assert_allclose(r2, 10.0 * r1, rtol=1e-9)
    # The drawn reference circle is the chart's base circle.
    np.testing.assert_allclose(np.linalg.norm(np.asarray(s.ring.reference.points)[:, 0, :2], axis=1), s.ring.scale.base_mm, rtol=1e-5)
    s.controls.magnification.value = 10000.0


def test_the_polar_chart_keeps_every_repetition_off_the_centre_and_labels_its_circles(browser) -> None:
    """At every offered magnification, with each repetition shown, nothing drawn reaches the centre;
    each scale circle's label in the flat polar plot says the deviation its radius stands for, and
    the plot writes the magnification and scale (the 3D chart writes only point numbers and theta)."""
    from ph_explorer.figures.polar import INNER_CLEARANCE, offered_magnifications

    s = browser
    s.go_to(15.0, -20.0)
    s.controls.repetitions.value = True
    for m in offered_magnifications():
        s.controls.magnification.value = float(m)
        scale = s.ring.scale
        assert scale.magnification == m
        reps = np.asarray(s.ring.repetitions.points)[:, 0, :2]
        assert np.linalg.norm(reps, axis=1).min() >= INNER_CLEARANCE * scale.base_mm - 1e-3
        for text, radius in scale.labelled_circles():
            assert f">{text}" in s.polar.plot.content  # the flat chart labels every circle
            assert np.isclose(radius, scale.base_mm + m * 1e-3 * float(text.split(" um")[0]), rtol=1e-5)
        assert f"x{m:g}, " in s.polar.plot.content  # the scale, beside the scene
    s.controls.repetitions.value = False
    s.controls.magnification.value = 10000.0


def test_unmeasured_orientation_is_labelled_a_prediction(browser) -> None:
    s = browser
    s.go_to(37.0, 123.0)
    assert not s.view.measured
    assert "measured" not in s.view.curves and not s.ring.curves["measured"].visible
    assert "prediction" in s.tables.markdown.content.lower()
    assert "prediction" in s.ring.title.lower() and "prediction" in s.polar.plot.content.lower()
    assert "Table 3 needs a measurement" in s.tables.markdown.content


def test_tables_show_the_core_figures_for_a_check_ring(browser, dataset: Dataset) -> None:
    from ph_explorer.paper.tables import orientation_tables

    s = browser
    s.go_to(43.0, 90.0)
    i = dataset.campaign.index_of(43.0, 90.0)
    mask = np.zeros(dataset.campaign.n_orientations, bool)
    mask[i] = True
    row = orientation_tables(dataset.campaign, dataset.models, mask)[0]
    text = s.tables.markdown.content
    assert "held out" in text
    assert f"{row['range_um']['measured']:.2f}" in text
    assert f"{row['mae_um']['trilinear']['single']:.2f}" in text
    # The deviation chart carries the drawn curves.
    assert list(s.charts.drawn["deviation"])[:2] == ["measured", "trilinear"]
    np.testing.assert_allclose(s.charts.drawn["deviation"]["measured"], s.view.curves["measured"])
    assert (
        "measured mean" in s.charts.deviation.content and 'aria-label="chart Deviation against point number"' in s.charts.deviation.content
    )


def test_harmonic_chart_bars_are_the_spectrum(browser) -> None:
    from ph_explorer.harmonics import harmonic_spectrum

    s = browser
    s.go_to(75.0, 40.0)
    amp = harmonic_spectrum(s.view.curves["measured"])[0]
    measured = s.charts.drawn["harmonics"]["measured"]  # UPR 2, 3, ...
    for k in (2, 3, 6):
        assert measured[k - 2] == pytest.approx(amp[k], rel=1e-9)
        assert f"<title>measured mean, {k}: {amp[k]:.3g}</title>" in s.charts.harmonics.content  # its bar


def test_presets_and_marker_clicks_move_the_sliders(opened) -> None:
    fake, s = opened
    fake.click("Paper", "A75 B40")
    assert wait_for(lambda: s.orientation == (75.0, 40.0) and (s.view.a_deg, s.view.b_deg) == (75.0, 40.0))
    i = int(np.flatnonzero((s.field.orientations == [45.0, -20.0]).all(axis=1))[0])
    s.field.pick(i)
    assert s.orientation == (45.0, -20.0)
    # The field is hidden (its marker is not sent on every move); shown, it marks where the stylus points.
    assert not s.field.current.visible
    s.map_panel.show.value = True
    assert s.field.current.visible
    np.testing.assert_allclose(
        s.field.current.position / np.linalg.norm(s.field.current.position), stylus_direction(45.0, -20.0), atol=1e-6
    )
    s.map_panel.show.value = False


def test_error_map_shows_the_chosen_figure_and_goes_to_a_chosen_ring(opened, dataset: Dataset) -> None:
    from ph_explorer.harmonics import ron_t

    fake, s = opened
    # The map starts on where the model fails out of sample (um), not on the roundness; the 3D field is off.
    assert s.map_panel.figure.value == "trilinear MAE, leave-one-out"
    s.wait()
    loo = dataset.figure("trilinear MAE, leave-one-out")
    np.testing.assert_allclose(s.field.values, loo.values)
    assert not s.map_panel.show.value and not s.field.markers.visible and not s.field.current.visible
    svg = s.map_panel.plot.content
    assert svg.startswith("<svg") and "A (deg)" in svg and "B (deg)" in svg and ">um</text>" in svg
    # The Worst dropdown lists the largest values with their unit.
    worst = s.controls.worst.options[1]
    a, b = (float(t[1:]) for t in worst.split()[:2])
    j = int(np.nanargmax(loo.values))
    assert (a, b) == tuple(dataset.campaign.orientations[j]) and worst.endswith(" um)")
    # Another figure, chosen in the browser: the field and the map follow.
    fake.click("Map of", "measured RONt")
    assert wait_for(
        lambda: s.map_panel.plot.content.count("measured RONt") >= 1 and np.allclose(s.field.values, ron_t(dataset.campaign.mean_curves()))
    )
    # The ring picker, as the browser sends it: the sliders go there, the map marks it.
    option = s.map_panel.ring.options[3]
    a, b = (float(t[1:]) for t in option.split()[:2])
    fake.click("Go to ring", option)
    assert wait_for(lambda: s.orientation == (a, b) and (s.view.a_deg, s.view.b_deg) == (a, b))
    s.wait()
    x = 46.0 + (b + 180.0) / 360.0 * 342.0  # the map's plot box: B across from x = 46, 342 wide
    assert (
        f'<line x1="{x:.1f}" y1="26.0" x2="{x:.1f}" y2="236.0" stroke="#111"' in s.map_panel.plot.content
    )  # the current orientation's cross hair
    # Before a diagnosis, the failing rings are not named, and the panel says why.
    assert "Not diagnosed yet" in s.map_panel.failing_text.content and not s.map_panel.failing_buttons
    # The 3D field on request.
    fake.click("3D field around the head")
    assert wait_for(lambda: s.field.markers.visible)
    # An off-the-shelf peer beside the models, fitted when first shown: values on the check rings only.
    fake.click("Map of", "rbf MAE / noise floor, check rings")
    assert wait_for(lambda: "rbf MAE / noise floor" in s.map_panel.plot.content)
    assert np.isfinite(s.field.values[dataset.held_out_mask]).all() and np.isnan(s.field.values[~dataset.held_out_mask]).all()


def test_monte_carlo_band_and_repetitions_on_request(browser) -> None:
    s = browser
    s.go_to(15.0, -20.0)
    assert not s.ring.repetitions.visible
    s.controls.repetitions.value = True
    assert s.ring.repetitions.visible
    assert np.asarray(s.ring.repetitions.points).shape[0] == s.dataset.campaign.n_repetitions * s.dataset.campaign.n_points
    s.controls.band.value = "trilinear"
    assert s.ring.band is not None and s.ring.band.visible
    s.controls.band.value = "none"
    assert not s.ring.band.visible


def test_the_band_shows_what_the_model_uncertainty_adds_and_table_1_the_tasks_ront(browser) -> None:
    """Issue 17, item 5: the band with and without the model's own error; RONt +- U of one
    measurement beside Table 1, computed once the sliders rest (… meanwhile)."""
    s = browser
    s.go_to(43.0, 90.0)  # a check ring: measured, held out of training
    s.controls.band.value = "trilinear"

    def band_width() -> float:
        vertices = np.asarray(s.ring.band.vertices, dtype=float)
        n = vertices.shape[0] // 2
        return float(np.mean(np.linalg.norm(vertices[n:, :2], axis=1) - np.linalg.norm(vertices[:n, :2], axis=1)))

    with_error = band_width()
    s.controls.band_model_error.value = False
    without = band_width()
    assert 0 < without < with_error
    s.controls.band_model_error.value = True
    assert band_width() == pytest.approx(with_error)
    # The band of the mean of the repetitions (to compare with the measured mean): narrower, and the
    # model uncertainty a larger share of it.
    s.controls.band_of.value = s.controls.band_of.options[1]
    mean_with = band_width()
    s.controls.band_model_error.value = False
    mean_without = band_width()
    assert 0 < mean_without < mean_with < with_error and mean_with / mean_without > with_error / without
    s.controls.band_model_error.value = True
    s.controls.band_of.value = s.controls.band_of.options[0]
    assert band_width() == pytest.approx(with_error)

    def rows() -> dict[str, str]:
        """The RONt table under Table 1: a curve a row (a narrow panel keeps each figure on one line)."""
        lines = s.tables.markdown.content.splitlines()
        start = lines.index(RONT_HEADER) + 2
        cells = [[c.strip() for c in line.strip("|").split("|")] for line in lines[start:] if line.startswith("|")]
        return {name: cell for name, cell in cells[: 1 + len(s.dataset.model_names)]}

    assert wait_for(lambda: "…" not in rows().values(), timeout=120), rows()
    assert list(rows()) == ["measured", *s.dataset.model_names]  # measured and every model
    for cell in rows().values():
        assert " " not in cell  # no-break spaces: "1.111 ± 0.327" is never broken
        value, u = (float(x) for x in cell.split("±"))
        assert value > 0 and u > 0
    s.tables.task.value = False
    assert RONT_HEADER not in s.tables.markdown.content


class WatchedSlots:
    """The app's bound on heavy jobs with its two slots held by the test, saying when a job asks for one and is done."""

    def __init__(self) -> None:
        self.slots = threading.BoundedSemaphore(2)
        self.asked, self.done = threading.Event(), threading.Event()
        for _ in range(2):
            self.slots.acquire()

    def __enter__(self) -> None:
        self.asked.set()
        self.slots.acquire()

    def __exit__(self, *_: object) -> None:
        self.slots.release()
        self.done.set()


def test_a_browser_that_leaves_has_no_more_ront_computed_for_it(app: ExplorerApp) -> None:
    """Its RONt job waiting for a slot when the browser closes stops there: nobody would see it, and
    a room's thirty leaving browsers kept the server's two cores busy for half a minute."""
    fake, s = open_session(app)
    slots = WatchedSlots()
    s.shared = dataclasses.replace(s.shared, heavy=slots)  # this browser's jobs only
    s.go_to(31.5, 77.5)  # not measured, not asked before: its RONt is wanted once the sliders rest
    assert slots.asked.wait(30), "the resting sliders asked for no RONt"
    fake.close()
    assert wait_for(lambda: s.client.client_id not in app.sessions)
    slots.slots.release()
    slots.slots.release()
    assert slots.done.wait(60)
    assert all(app.dataset.cached_task(m, 31.5, 77.5) is None for m in app.dataset.model_names)


def test_thirty_browsers_at_once_each_keep_their_own_state(app: ExplorerApp) -> None:
    before = set(app.sessions)
    browsers = [FakeBrowser(app.port) for _ in range(30)]
    try:
        wait_for(lambda: len(set(app.sessions) - before) >= 30, timeout=120)
        sessions = [app.sessions[k] for k in sorted(set(app.sessions) - before)]
        assert len(sessions) == 30
        targets = [(float(3 * k % 116), float(-170 + 11 * k)) for k in range(30)]
        # Everyone moves at the same time, from their own thread (as their callbacks would).
        threads = [threading.Thread(target=s.go_to, args=t) for s, t in zip(sessions, targets)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(30)
        for s, (a, b) in zip(sessions, targets):
            assert s.orientation == (a, b)
            assert (s.view.a_deg, s.view.b_deg) == (a, b)
            r = rotation_of(s.head.b_frame.wxyz) @ rotation_of(s.head.a_frame.wxyz)
            np.testing.assert_allclose(r, head_rotation(a, b), atol=1e-9)
            assert f"A{a:g} B{b:g}" in s.tables.markdown.content
    finally:
        for b in browsers:
            b.close()


def test_a_slider_move_from_the_browser_reaches_only_its_session(app: ExplorerApp) -> None:
    (one, s1), (two, s2) = open_session(app), open_session(app)
    try:
        a2 = s2.orientation
        one.move_slider("A (deg)", 60.0)
        # The render thread draws it after the callback: wait for the drawn view, not just the value.
        assert wait_for(lambda: s1.orientation[0] == 60.0 and s1.view.a_deg == 60.0)
        np.testing.assert_allclose(rotation_of(s1.head.a_frame.wxyz), head_rotation(60.0, 0.0), atol=1e-9)  # the A joint alone
        assert s2.orientation == a2
    finally:
        one.close()
        two.close()


def test_browser_moves_wait_for_the_one_render_thread_and_the_latest_value_wins(app: ExplorerApp) -> None:
    """A browser's slider messages only mark its session dirty; the app's render thread draws each
    dirty session once with its latest values (the scheduling itself: tests/test_render_queue.py)."""
    (b1, s1), (b2, s2) = open_session(app), open_session(app)
    started, release = threading.Event(), threading.Event()

    def held() -> None:  # keeps the render thread busy until released
        started.set()
        release.wait(10)

    try:
        app.renders.request(RenderState(held))
        assert started.wait(10)
        renders = s1.render_count, s2.render_count
        for a in (20.0, 21.0, 22.0, 23.0):
            b1.move_slider("A (deg)", a)
        for a in (61.0, 62.0):
            b2.move_slider("A (deg)", a)
        assert wait_for(lambda: s1.orientation[0] == 23.0 and s2.orientation[0] == 62.0)
        # viser sets a slider's value before it runs the callbacks that mark the session dirty.
        assert wait_for(lambda: not s1.render_state.idle and not s2.render_state.idle)
        assert (s1.render_count, s2.render_count) == renders  # nothing drawn in viser's callback threads
        release.set()
        assert s1.wait_rendered(10) and s2.wait_rendered(10)
    finally:
        release.set()
        b1.close()
        b2.close()
    assert (s1.render_count, s2.render_count) == (renders[0] + 1, renders[1] + 1)  # the moves coalesced
    assert s1.view.a_deg == 23.0 and s2.view.a_deg == 62.0
    # Its latency covers the wait behind the held render; the render itself was not held.
    assert s2.render_state.latency_times[-1] > s2.render_state.render_times[-1]


def test_a_bad_upload_keeps_the_data_and_shows_the_error(browser) -> None:
    s = browser
    before = s.dataset
    s.load_upload("broken.csv", b"A_deg,B_deg,rep,point,dev_um\n0,0,0,0,abc\n")
    assert s.dataset is before
    message = s.data_panel.message.content
    assert "broken.csv" in message and "row" in message and "keeps its current data" in message
    assert "/tmp" not in message


def test_a_good_upload_replaces_the_session_data_only(browser, app: ExplorerApp, tmp_path) -> None:
    campaign = lobing_campaign(seed=9, n_repetitions=3, extra_orientations=((30.0, 50.0),))
    path = write_campaign(campaign, tmp_path / "mine.csv")
    s = browser
    s.load_upload("mine.csv", path.read_bytes())
    assert s.dataset is not app.dataset
    assert s.dataset.campaign.n_repetitions == 3
    assert "mine.csv" in s.data_panel.source.content
    assert app.dataset.campaign.n_repetitions == 10
    s.go_to(30.0, 50.0)
    assert s.view.measured


def test_an_uploaded_sidecar_gives_the_browser_the_check_rings_and_geometry_the_command_line_reads(opened, tmp_path) -> None:
    """A browser sends one file at a time: the CSV alone is read with the default check rings and
    geometry, and says so; its sidecar TOML, uploaded next, gives the session what `read_campaign`
    (the command line) reads from NAME.csv beside NAME.toml. A sidecar with no CSV uploaded, or a
    bad one, is one line and the data stays."""
    from ph_explorer.io import read_campaign

    fake, s = opened
    fake.upload("Upload its sidecar TOML", "lab.toml", b"[geometry]\n")
    assert wait_for(lambda: "upload the campaign CSV first" in s.data_panel.message.content)
    campaign = lobing_campaign(seed=5, n_repetitions=3, check_orientations=((15.0, -20.0), (45.0, 40.0), (75.0, 100.0)))
    campaign.geometry = dataclasses.replace(campaign.geometry, pivot_to_ball_mm=campaign.geometry.pivot_to_ball_mm + 20.0)
    path = write_campaign(campaign, tmp_path / "lab.csv")
    expected = read_campaign(path)
    fake.upload("Upload a campaign CSV", "lab.csv", path.read_bytes())
    assert wait_for(lambda: "without a sidecar" in s.data_panel.message.content, timeout=120)
    s.wait(timeout=120)
    assert s.dataset.campaign.geometry != expected.geometry
    assert not np.array_equal(s.dataset.campaign.holdout_mask(), expected.holdout_mask())
    fake.upload("Upload its sidecar TOML", "lab.toml", b"[geometry]\nstylus = 3\n")
    assert wait_for(lambda: "Not loaded" in s.data_panel.message.content, timeout=120)
    assert "lab.toml" in s.data_panel.message.content and "/tmp" not in s.data_panel.message.content
    fake.upload("Upload its sidecar TOML", "lab.toml", path.with_suffix(".toml").read_bytes())
    assert wait_for(lambda: "with its sidecar **lab.toml**" in s.data_panel.message.content, timeout=120)
    s.wait(timeout=120)
    assert s.dataset.campaign.geometry == expected.geometry
    np.testing.assert_array_equal(s.dataset.campaign.holdout_mask(), expected.holdout_mask())
    assert "3 check rings" in s.data_panel.message.content and "uploaded lab.csv" in s.data_panel.source.content


def test_a_campaign_with_negative_a_is_shown(opened, app: ExplorerApp, tmp_path) -> None:
    """The A slider's range comes from the data: a campaign with negative A reaches them (issue 12)."""
    fake, s = opened
    assert (s.controls.a.min, s.controls.a.max) == (0.0, A_LIMIT_DEG)  # the test campaign: A 0..90
    campaign = lobing_campaign(seed=7, n_repetitions=3, extra_orientations=((-30.0, 60.0), (-75.0, -140.0)))
    s.load_upload("negative.csv", write_campaign(campaign, tmp_path / "negative.csv").read_bytes())
    assert "negative.csv" in s.data_panel.source.content
    assert (s.controls.a.min, s.controls.a.max) == (-A_LIMIT_DEG, A_LIMIT_DEG)
    assert wait_for(lambda: fake.props("A (deg)")["min"] == -A_LIMIT_DEG)  # what the browser's slider shows
    s.go_to(-30.0, 60.0)
    assert s.orientation == (-30.0, 60.0) and s.view.measured and s.ring.curves["measured"].visible
    np.testing.assert_allclose(rotation_of(s.ring.frame.wxyz), head_rotation(-30.0, 60.0), atol=1e-9)
    # A click on the ring's marker in the field lands on it, not on A = 0.
    s.go_to(15.0, -20.0)
    i = int(np.flatnonzero((s.field.orientations == [-75.0, -140.0]).all(axis=1))[0])
    s.field.pick(i)
    assert s.orientation == (-75.0, -140.0) and s.view.measured
    # Back to data without negative A: the slider's range and value follow.
    s.load_upload("positive.csv", write_campaign(lobing_campaign(seed=8, n_repetitions=3), tmp_path / "positive.csv").read_bytes())
    assert (s.controls.a.min, s.orientation[0], s.view.a_deg) == (0.0, 0.0, 0.0)


def test_physics_panel_lists_the_catalog_effects(browser) -> None:
    p = browser.physics
    assert set(p.effects) == set(DEFAULT_CATALOG.candidates())
    assert browser.catalog is DEFAULT_CATALOG
    assert all(not box.value for box in p.effects.values())
    assert not p.history.visible and p.candidates.content == ""


def test_teaching_only_controls_show_for_a_teaching_scenario_only(browser, tmp_path) -> None:
    """Issue 57, item 8: Reveal and the report's naming of hidden effects are for a campaign that
    records hidden effects (a teaching scenario); a lab's CSV, uploaded, hides them; a teaching
    scenario loaded after it shows them again."""
    s = browser

    def shown() -> tuple[bool, bool]:
        return bool(s.physics.reveal.visible), bool(s.report_panel.reveal.visible)

    assert shown() == (False, False)  # the served synthetic campaign records nothing hidden
    taught = lobing_campaign(seed=4, n_repetitions=3)
    taught.scenario = {"name": "synthetic lobing", "hidden": ["lobing"], "effects": [{"id": "lobing", "hidden": True}]}
    s._new_data(taught, "a teaching scenario")
    assert shown() == (True, True)
    s.load_upload("lab.csv", write_campaign(taught, tmp_path / "lab.csv").read_bytes())  # the CSV alone: no sidecar
    assert "lab.csv" in s.data_panel.source.content and shown() == (False, False)
    s._new_data(taught, "a teaching scenario again")
    assert shown() == (True, True)


def test_reveal_says_when_nothing_is_hidden(opened) -> None:
    fake, s = opened
    fake.click("Reveal the hidden effect")
    assert wait_for(lambda: "no hidden effect" in s.physics.revealed.content)


def test_refit_without_a_diagnosis_records_the_baseline_then_the_step(opened) -> None:
    """Refit alone works too: add_effects gives the baseline step, then the hybrid's step. With
    nothing ticked and nothing added before, a refit would repeat the baseline: it says so instead."""
    fake, s = opened
    click(fake, s, "Refit the hybrid")
    assert s.loop.steps == [] and "Nothing to refit" in s.physics.refit_status.content
    s.physics.effects["lobing"].value = True
    click(fake, s, "Refit the hybrid")
    assert [step.added for step in s.loop.steps] == [(), ("lobing",)]
    assert s.physics.history.visible and s.physics.history.content.count('fill="#1f77b4"><title>') == 2  # two steps, vs the mean
    assert "hybrid" in s.dataset.models
    # The fitted parameters are written by the effect itself, with their units.
    fitted = s.loop.steps[-1].params[0]["params"]
    assert DEFAULT_CATALOG["lobing"].parameters_text(fitted) in s.physics.refit_status.content
    # Untick everything and refit: the hybrid curve goes away, the history keeps growing.
    s.physics.effects["lobing"].value = False
    click(fake, s, "Refit the hybrid")
    assert len(s.loop.steps) == 3 and "hybrid" not in s.dataset.models and not s.ring.curves["hybrid"].visible
    click(fake, s, "Refit the hybrid")
    assert len(s.loop.steps) == 3 and "Nothing to refit" in s.physics.refit_status.content


def test_sliders_stay_live_while_a_diagnosis_runs_and_its_verdict_is_shown(app: ExplorerApp, monkeypatch) -> None:
    """Heavy work runs on the session's worker: both this and another browser's sliders render meanwhile.

    The synthetic campaign's curves turn with B0 faster than leave-one-out interpolation follows and
    are no catalog effect: the verdict reads "unexplained" or "partial", and says so in the panel.
    """
    from ph_explorer.app import physics

    running, release = threading.Event(), threading.Event()
    real = physics.diagnosis.diagnose

    def held_diagnose(*args, **kwargs):
        running.set()
        release.wait(60)  # the diagnosis is "still running" until the sliders have been moved
        return real(*args, **kwargs)

    monkeypatch.setattr(physics.diagnosis, "diagnose", held_diagnose)
    (b1, s1), (b2, s2) = open_session(app), open_session(app)
    try:
        b1.click("Diagnose")
        assert running.wait(30) and wait_for(lambda: bool(s1.jobs))  # the callback lists the job after submitting it
        job = s1.jobs[-1]
        counts = s1.render_count, s2.render_count
        s1.controls.a.value = 52.0
        s2.go_to(30.0, 60.0)
        assert not job.done()  # the renders happened while the diagnosis was running
        assert s1.render_count > counts[0] and s2.render_count > counts[1]
        assert s1.view.a_deg == 52.0 and (s2.view.a_deg, s2.view.b_deg) == (30.0, 60.0)
        release.set()
        s1.wait(timeout=120)
        # No catalog effect explains it all: the model still fails beyond noise, with or without
        # the axis motions that explain a part of it.
        verdict = s1.loop.diagnosis.verdict if s1.loop.diagnosis is not None else None
        assert verdict in ("unexplained", "partial")
        assert f"Verdict: {verdict}" in s1.physics.verdict.content
        # The verdicts the diagnosis could give, this one marked (under "More", the verdict kept short).
        from ph_explorer.diagnosis import VERDICTS

        assert all(f"{key}: {meaning}" in s1.physics.verdict_more.content for key, meaning in VERDICTS.items() if key != verdict)
        assert f"**{verdict}** ✔: {VERDICTS[verdict]}" in s1.physics.verdict_more.content
        shown = s1.physics.candidates.content.replace("<wbr>", "")  # an id breaks after its underscores
        assert any(effect_id in shown for effect_id in app.shared.catalog.candidates())
        assert s2.loop.diagnosis is None and s2.physics.verdict.content == ""  # the other browser is untouched
        # Where it fails: the rings the within-noise test finds beyond their noise, worst first by
        # their error over their floor, a button each; one click goes there.
        from ph_explorer.app.map_panel import MAX_FAILING_BUTTONS, failing_label

        rings = s1.loop.diagnosis.failing_rings()
        assert rings and [r.ratio for r in rings] == sorted((r.ratio for r in rings), reverse=True)
        labels = [button.label for button in s1.map_panel.failing_buttons]
        assert labels == [failing_label(r) for r in rings[:MAX_FAILING_BUTTONS]]
        assert f"{rings[0].mae_um['mean']:.3f} um, floor {rings[0].floor_um['mean']:.3f} um" in labels[0]
        assert f"{len(rings)} rings exceed their noise" in s1.map_panel.failing_text.content
        target = rings[min(1, len(rings) - 1)]
        b1.click(failing_label(target))
        assert wait_for(lambda: s1.orientation == (target.a_deg, target.b_deg))
        # The diagnosis's per-ring verdict on the map: exceeds where the test says so.
        verdict = "diagnosis: ring verdict (within-noise test)"
        assert verdict in s1.map_panel.figure.options and verdict not in s2.dataset.figure_names()  # this browser's only
        b1.click("Map of", verdict)
        assert wait_for(lambda: np.array_equal(s1.field.values, s1.loop.diagnosis.failing.astype(float)))
        assert wait_for(lambda: "exceeds its noise" in s1.map_panel.plot.content)  # drawn after the values, on the render thread
        assert "Not diagnosed yet" in s2.map_panel.failing_text.content
    finally:
        release.set()
        b1.close()
        b2.close()


@pytest.mark.slow
def test_teaching_loop_diagnose_add_refit_error_falls(opened, tmp_path) -> None:
    """Done-when of issue 6: on a teaching scenario the GUI loop diagnose -> add -> refit lowers the error."""
    fake, s = opened
    s.data_panel.scenario.value = s.data_panel.label_of("head_3")
    s.wait(timeout=300)
    assert "head_3" in s.data_panel.source.content and s.data_panel.chosen() == "head_3"  # the box names what is shown
    click(fake, s, "Diagnose", timeout=600)
    p = s.physics
    best = s.loop.diagnosis.candidates[0]
    assert best.effect == "b_axis_cyclic" and best.settings["cycles_per_rev"] == 22 and best.significant
    # The ranked table, the verdict with units and the teaching text, the evidence chart.
    assert "b_<wbr>axis_<wbr>cyclic" in p.candidates.content and f"{100 * best.explained_fraction:.1f}" in p.candidates.content
    assert "Verdict: missing" in p.verdict.content
    assert DEFAULT_CATALOG["b_axis_cyclic"].parameters_text(best.params, best.params_u) in p.fit.content
    # The teaching text once, under "More" with the tests' figures; not again in the evidence or Reveal.
    assert "arcsec" in p.fit.content and best.teaching in p.verdict_more.content
    assert best.teaching not in p.verdict.content and best.teaching not in p.evidence_text.content
    assert list(p.effects)[0] == "b_axis_cyclic" and p.found_folder.visible  # the found effect first, ready to tick
    # The signature plot (SVG): a dot per bin of the residual, the fitted term, the variable it is read against.
    assert p.results_folder.visible and p.evidence_of.value == "b_axis_cyclic"
    assert p.evidence.content.count('r="2.6"') == 1 + len(best.evidence["residual"])  # the dots and the legend's
    assert "B joint angle" in p.evidence.content and 'aria-label="signature plot b_axis_cyclic' in p.evidence.content
    assert "identifiable" in p.fit.content or "confounded" in p.fit.content
    other = s.loop.diagnosis.candidates[1]
    p.evidence_of.value = other.effect  # another candidate's evidence on request
    assert wait_for(lambda: f'aria-label="signature plot {other.effect}' in p.evidence.content)
    assert other.name in p.evidence_text.content
    # The history starts at the baseline.
    assert len(s.loop.steps) == 1 and s.loop.steps[0].added == () and not p.history.visible  # one point: the fall line says it
    baseline = s.loop.steps[0]
    p.effects["b_axis_cyclic"].value = True
    click(fake, s, "Refit the hybrid", timeout=600)
    last = s.loop.steps[-1]
    print("history", [(st.added, st.mae_um, st.noise_floor_um) for st in s.loop.steps])
    assert last.added == ("b_axis_cyclic",)
    assert last.mae_um["mean"] < baseline.mae_um["mean"]
    assert last.mae_um["mean"] <= 1.3 * last.noise_floor_um["mean"], last
    # The chart: the steps named on the axis; MAE and floor against the mean and single repetitions per step.
    chart = p.history.content
    assert ">baseline</tspan>" in chart and ">+ b_axis_cyclic</tspan>" in chart
    for step, name in ((baseline, "baseline"), (last, "+ b_axis_cyclic")):
        assert f"{name}: {step.mae_um['mean']:.3f} um vs mean, floor {step.noise_floor_um['mean']:.3f}" in chart
        assert f"{name}: {step.mae_um['single']:.3f} um vs single, floor {step.noise_floor_um['single']:.3f}" in chart
    assert "+ b_axis_cyclic" in p.history_table.content
    # The fall in one line above Reveal and the chart: first step -> last, over the last step's floor.
    assert f"{baseline.mae_um['mean']:.3f} -> **{last.mae_um['mean']:.3f} um**" in p.fall.content
    # Beside the history, the honest "after": the choice cross-validated (nested), before and after.
    nested = s.loop.diagnosis.nested
    assert nested is not None and f"| after | {nested.after_um['mean']:.3f} | {nested.after_um['single']:.3f} |" in p.history_table.content
    assert f"| before | {nested.before_um['mean']:.3f} |" in p.history_table.content
    # The hybrid curve is in the scene, the charts and the tables.
    assert "hybrid" in s.dataset.models
    s.go_to(43.0, 90.0)
    assert "hybrid" in s.view.curves and s.ring.curves["hybrid"].visible
    assert "hybrid" in s.charts.drawn["deviation"]
    assert "hybrid" in s.tables.markdown.content
    fake.click("Reveal the hidden effect")
    assert wait_for(lambda: "b_axis_cyclic" in p.revealed.content)
    # The truth from the sidecar next to what was found: the diagnosis's fit with its uncertainty, the refit.
    assert "truth: amplitude 1 arcsec" in p.revealed.content and "22 cycles/rev" in p.revealed.content
    assert DEFAULT_CATALOG["b_axis_cyclic"].parameters_text(best.params, best.params_u) in p.revealed.content
    assert "last refit: amplitude" in p.revealed.content and best.teaching not in p.revealed.content
    assert s.report_panel.reveal.value  # the report names it too, as its checkbox now says
    # New data clears the physics of the old.
    s.data_panel.scenario.value = s.data_panel.label_of("paper")
    s.wait(timeout=300)
    assert s.loop.steps == [] and s.loop.diagnosis is None and not p.history.visible and "hybrid" not in s.dataset.models
    # An upload after a scenario and a report: neither the scenario box nor the report's line stays.
    s.report_panel.status.content = "Report sent: **report_paper.html**"
    s.load_upload("mine.csv", write_campaign(lobing_campaign(seed=9, n_repetitions=3), tmp_path / "mine.csv").read_bytes())
    assert "mine.csv" in s.data_panel.source.content
    assert s.data_panel.scenario.value == NO_CHOICE and s.report_panel.status.content == "" and not p.revealed.content


# -- the default start: the shipped paper campaign with assets/models/paper -----------------------------------


@pytest.fixture(scope="module")
def default_app():
    explorer = build_server(port=0)
    yield explorer
    explorer.stop()


def test_default_start_shows_measured_network_and_trilinear(default_app: ExplorerApp) -> None:
    app = default_app
    assert app.dataset.model_names == ["network", "trilinear"]
    assert app.startup_s > 0
    fake, s = open_session(app)
    try:
        view = s.view
        assert view.measured and view.held_out  # A15 B-20: a check ring of assets/models/paper
        for name in ("measured", "network", "trilinear"):
            assert s.ring.curves[name].visible, name
        assert list(s.charts.drawn["deviation"]) == ["measured", "network", "trilinear"]
        text = s.tables.markdown.content
        assert "| um | measured | network | trilinear |" in text
        mae = view.tables["mae_um"]["network"]["mean"]
        assert f"{mae:.2f}" in text and mae > 0
        assert "network" in s.controls.legend.content
        # An unseen orientation: the network predicts it.
        s.go_to(43.0, 100.0)
        assert not s.view.measured and s.ring.curves["network"].visible
        assert len(s.render_state.render_times) >= 2 and all(t > 0 for t in s.render_state.render_times)
    finally:
        fake.close()


def test_the_guis_diagnosis_starts_from_the_loaded_network(default_app: ExplorerApp, monkeypatch) -> None:
    """Item 6 of issue 15: the loaded model is the baseline, as `diagnose --model` takes it."""
    from ph_explorer.app import physics
    from ph_explorer.errors import InputError

    seen = []

    def watched(campaign, **kwargs):
        seen.append(kwargs["baseline"])
        raise InputError("stopped by the test")  # the baseline is what this test reads; the search is tested elsewhere

    monkeypatch.setattr(physics.diagnosis, "diagnose", watched)
    fake, s = open_session(default_app)
    try:
        click(fake, s, "Diagnose")
        assert seen == [default_app.dataset.models["network"]]
        assert "stopped by the test" in s.physics.status.content
    finally:
        fake.close()


def test_model_checkboxes_exist_with_their_models_and_a_scenario_switch_shows_its_progress(browser, monkeypatch) -> None:
    """Item 4 of issue 15: no ticked, greyed checkbox of a model that does not exist; a scenario
    switch (seconds: simulate, fit, draw) shows what it is doing above the fold, then hides."""
    import ph_explorer.app.session as session_module

    s = browser
    assert s.dataset.model_names == ["trilinear"]
    assert [name for name, box in s.controls.show.items() if box.visible] == ["measured", "trilinear"]
    assert not s.ring.curves["hybrid"].visible and not s.controls.busy.visible
    seen = []
    fit = session_module.dataset_for

    def watched(*args, **kwargs):
        seen.append((s.controls.busy.visible, s.controls.busy.value, s.controls.busy_text.content))
        return fit(*args, **kwargs)

    monkeypatch.setattr(session_module, "dataset_for", watched)
    s.load_scenario("paper")
    assert seen and seen[0][0] and 0.0 < seen[0][1] < 100.0 and "paper: fitting the models" in seen[0][2]
    assert not s.controls.busy.visible and not s.controls.busy_text.visible
    assert "paper" in s.data_panel.source.content


def test_serve_with_the_operators_effect_file_offers_its_effects_and_a_browser_uploads_no_code(tmp_path) -> None:
    """Item 9 of issue 15: `serve --effects FILE.py` (build_server(effects=...)) puts the file's effects
    in every browser's catalog; what a browser uploads is read as a campaign CSV, never run."""
    from ph_explorer import paths

    example = paths.assets_dir() / "effects_example.py"
    csv = write_campaign(lobing_campaign(seed=9, n_repetitions=3), tmp_path / "small.csv")
    explorer = build_server(data=csv, port=0, effects=example)
    try:
        fake, s = open_session(explorer)
        try:
            assert "my_ball_form" in s.catalog and "my_ball_form" in s.physics.effects
            assert set(DEFAULT_CATALOG.candidates()) < set(s.physics.effects)
            before = s.dataset
            s.load_upload("effects.py", example.read_bytes())  # code sent as a campaign: refused, not run
            assert "Not loaded" in s.data_panel.message.content and s.dataset is before
            assert list(s.catalog) == list(explorer.shared.catalog)
        finally:
            s.wait(timeout=60)
            fake.close()
    finally:
        explorer.stop()


def test_serve_refuses_a_bad_effect_file_in_one_line_before_serving(tmp_path) -> None:
    import os
    import subprocess
    import sys

    from ph_explorer.errors import InputError

    clash = tmp_path / "clash.py"
    clash.write_text("from ph_explorer.effects.stylus import BallForm\n\nclass Again(BallForm):\n    id = 'lobing'\n", encoding="utf-8")
    with pytest.raises(InputError, match="already a built-in effect"):
        build_server(port=0, effects=clash)
    done = subprocess.run(
        [sys.executable, "-m", "ph_explorer", "serve", "--effects", str(tmp_path / "missing.py"), "--port", "0"],
        capture_output=True,
        text=True,
        env=dict(os.environ, COLUMNS="120"),
        timeout=120,
    )
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, (done.stdout, done.stderr)
    assert "effects file not found" in done.stderr and "serving" not in done.stdout


def test_a_gaussian_process_in_the_data_is_drawn_with_its_band_from_its_posterior(dataset: Dataset) -> None:
    """A model folder with a GP (`train --data-part gp`): its checkbox and curve appear, its band's
    model component comes from its posterior (no cross-validation), and the map offers its check-ring
    MAE over the floor."""
    from ph_explorer.models.gaussian_process import GaussianProcessModel
    from ph_explorer.uncertainty.model_error import PosteriorError

    gp = GaussianProcessModel().fit(dataset.campaign, dataset.train_mask)
    explorer = ExplorerApp(dataset.with_model("gp", gp), host="127.0.0.1", port=0)
    try:
        fake, s = open_session(explorer)
        assert s.dataset.model_names == ["trilinear", "gp"]
        assert [name for name, box in s.controls.show.items() if box.visible] == ["measured", "trilinear", "gp"]
        s.go_to(43.0, 90.0)
        assert s.ring.curves["gp"].visible
        assert isinstance(s.dataset.model_error("gp"), PosteriorError)
        lower, upper = s.dataset.band("gp", 43.0, 90.0)
        bare = s.dataset.band("gp", 43.0, 90.0, with_model_error=False)
        assert (upper - lower > bare[1] - bare[0]).all()
        assert "gp MAE / noise floor, check rings" in s.dataset.figure_names()
        fake.close()
    finally:
        explorer.stop()
