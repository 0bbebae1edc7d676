"""The model view (app/render/model_view.py) and the live model texture
(app/model_session.py), headless: picking hits the atlas texel under the
mouse, the camera's moves, the preview's levels coarse to fine and its final
atlas equal to the engine's, synthesis magnification sharper than the texture."""
import math
import os
from dataclasses import replace

import numpy as np
import pytest

from infinitex.app.render.model_view import ModelView, OrbitCamera
from infinitex.app.session import Session
from infinitex.engine.surface import Model
from infinitex.engine.surface.bake import atlas_coords
from infinitex.engine.surface.shapes import cube
from infinitex.export.surface import surface_controls
from infinitex.project import Document, ExemplarSource
from infinitex.project.surface import SurfaceSettings

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BRICK = os.path.join(ROOT, "infinitex", "assets", "brick.png")


def quad() -> Model:
    """A 2 x 2 square in the z = 0 plane facing +z, its UVs the unit square (v up)."""
    P = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float64)
    return Model(P, np.array([[0, 1, 2], [0, 2, 3]]), (P[:, :2] + 1) / 2, name="quad")


def test_picking_finds_the_atlas_texel_under_the_mouse(gpu):
    gpu.activate()
    q = quad()
    view = ModelView(gpu.ctx, q.positions, q.faces, q.uvs)
    cam = OrbitCamera(target=(0.0, 0.0, 0.0), yaw=0.0, pitch=0.0, distance=3.0)
    try:
        n = 256
        assert view.pick(cam, (200, 200), 100, 100, n) in ((127, 127), (128, 128), (127, 128), (128, 127))
        # Right of the centre is +x (u up), above it is +y (v up: atlas rows towards 0).
        right, up = view.pick(cam, (200, 200), 140, 100, n), view.pick(cam, (200, 200), 100, 60, n)
        assert right[0] > 140 and abs(right[1] - 128) <= 1
        assert up[1] < 116 and abs(up[0] - 128) <= 1
        assert view.pick(cam, (200, 200), 2, 2, n) is None  # the background
    finally:
        view.release()


def test_the_camera_orbits_zooms_and_pans():
    cam = OrbitCamera(target=(0.0, 0.0, 0.0), yaw=0.0, pitch=0.0, distance=2.0)
    assert np.allclose(cam.eye, [0, 0, 2])
    assert np.allclose(cam.orbit(90.0, 0.0).eye, [2, 0, 0])
    assert cam.orbit(0.0, 200.0).pitch == 89.0  # never over the pole
    assert cam.zoom(0.5).distance == 1.0
    moved = cam.pan(0.25, 0.0, 1.0)  # a quarter of the view to the right: the target goes left
    h = 2 * 2.0 * math.tan(math.radians(cam.fovy) / 2)
    assert np.allclose(moved.target, [-0.25 * h, 0, 0])


@pytest.fixture(scope="module")
def session(gpu):
    s = Session(gpu)
    doc = Document(ExemplarSource.from_file(BRICK), structure=0)
    s.load_now(doc)
    m = cube(n=2)
    doc = replace(doc, surface=SurfaceSettings(m, 256, repeats=2.0))
    s.sync(doc)
    yield s, doc
    s.release()


def test_the_live_texture_refines_coarse_to_fine_and_ends_as_the_engines(session):
    s, doc = session
    pv = s.model
    shown = []
    while not pv.step(0.01):
        if pv.image is not None and (not shown or shown[-1] != pv.image.shape[0]):
            shown.append(pv.image.shape[0])
    shown.append(pv.image.shape[0])
    assert shown[0] < 256 and shown[-1] == 256 and shown == sorted(shown)
    controls, _ = surface_controls(s.controls)
    s.synth.set_params(s.params, controls)
    assert np.array_equal(pv.coords(), atlas_coords(s.synth, pv.atlas, controls))
    # A change starts again, showing the old texture until the new one is as sharp.
    old = pv.image
    s.sync(replace(doc, seed=9))
    pv.step(0.001)
    assert pv.image is old
    while not pv.step(0.05):
        pass
    assert not np.array_equal(pv.image, old)
    s.sync(doc)
    while not pv.step(0.05):
        pass


def test_magnification_is_sharper_than_the_texture_up_close(gpu, session):
    s, doc = session
    pv = s.model
    while not pv.step(0.05):
        pass
    m = doc.surface.model
    gpu.activate()
    view = ModelView(gpu.ctx, m.positions, m.faces, m.uvs)
    try:
        view.set_texture(pv.image)
        close = OrbitCamera(target=(0.3, 0.3, 1.0), yaw=0.0, pitch=0.0, distance=0.6)
        plain = view.render(close, (200, 200)).astype(np.float64).mean(-1)
        view.set_synthesis(*pv.magnification())
        sharp = view.render(close, (200, 200)).astype(np.float64).mean(-1)

        def energy(a):
            return float((np.diff(a, axis=0) ** 2).mean() + (np.diff(a, axis=1) ** 2).mean())
        assert energy(sharp) > 3 * energy(plain)
        # The same mean colour: it is the same texture, drawn sharper.
        assert abs(sharp.mean() - plain.mean()) < 8
    finally:
        view.release()


def test_feature_handles_on_the_model_show_only_what_the_camera_sees(gpu):
    """tools/feature_model.py: a feature on the cube's face towards the camera
    has its handle where its centre projects, a disc of its radius on the
    surface, and can be grabbed; one on the far face is hidden and cannot be
    grabbed through the model; Jump to turns the camera to face it."""
    from types import SimpleNamespace

    from infinitex.app.ui.tools.feature_model import ModelFeatures
    from infinitex.engine.controls import Feature
    from infinitex.engine.surface import AtlasDomain
    gpu.activate()
    model = cube(n=3)
    n = 256
    atlas = AtlasDomain(model, n, sigma=40.0)
    view = ModelView(gpu.ctx, model.positions, model.faces, model.uvs)
    cam = OrbitCamera(target=(0.0, 0.0, 0.0), yaw=0.0, pitch=0.0, distance=4.0)  # looking at the +z face
    size = (400, 400)
    cache = {}

    def uv_image(w, h):
        key = (ed.model.camera, w, h)
        if key not in cache:
            cache[key] = view.render(ed.model.camera, (w, h), mode=1, background=(0, 0, 0))
        return cache[key]
    ed = SimpleNamespace(model=SimpleNamespace(camera=cam, uv_image=uv_image),
                         session=SimpleNamespace(model=SimpleNamespace(atlas=atlas)),
                         doc=SimpleNamespace(surface=SimpleNamespace(size=n), features=()))
    ed.model.look_with = lambda camera: setattr(ed.model, "camera", camera)  # (the editor's ModelMode.look_with)
    try:
        front = view.pick(cam, size, 200, 200, n)  # the +z face's centre
        mf = ModelFeatures(ed)
        p = mf.surface_point(front)
        assert abs(p[2] - 1.0) < 1e-6 and np.abs(p[:2]).max() < 0.05
        # The same face seen from behind: the -z face's centre (the atlas texel seen from the other side).
        back = view.pick(OrbitCamera(target=(0.0, 0.0, 0.0), yaw=180.0, pitch=0.0, distance=4.0), size, 200, 200, n)
        assert abs(mf.surface_point(back)[2] + 1.0) < 1e-6
        ed.doc.features = (Feature((5, 5), front, 20, 40), Feature((5, 5), back, 20, 40))
        handles = mf._handles(*size)
        assert [h[0] for h in handles] == [0]  # the far face's feature is hidden
        i, x, y, ri, ro = handles[0]
        assert abs(x - 200) <= 2 and abs(y - 200) <= 2
        # Outer radius 40 exemplar px = 1 world unit at sigma 40: the projected half-width of a unit at depth 3.
        want = size[1] / (2 * math.tan(math.radians(cam.fovy) / 2) * 3.0)
        assert ro == pytest.approx(want, rel=0.05) and ri == pytest.approx(want / 2, rel=0.05)
        assert mf._hit(200, 200, *size) == (0, "move")
        assert mf._hit(200 + ro, 200, *size) == (0, "outer")
        mf.jump_to(ed.doc.features[1])  # the far face: the camera turns round to it
        assert abs(((ed.model.camera.yaw - 180.0) + 180) % 360 - 180) < 1e-6 and abs(ed.model.camera.pitch) < 1e-6
        assert [h[0] for h in mf._handles(*size)] == [1]
    finally:
        view.release()


@pytest.mark.parametrize("theta", [0.0, 30.0, 90.0, 135.0])
def test_the_model_shows_the_direction_field_as_strokes_along_it(theta):
    """H with the Direction tool on a model shows the field (not the randomness):
    strokes only where it is painted, each along the painted direction."""
    from infinitex.app.render.overlays import direction_rgba
    from infinitex.engine.controls.direction import DirectionField
    n = 256
    field = DirectionField.uniform(theta, 1.2, 1.0, 0, 0, 128, 256)  # the left half (scale 1.2: 0 degrees is painted too)
    rgba = direction_rgba(field, n)
    on = rgba[..., 3] > 200  # the light core of the strokes
    assert on[:, :128].mean() > 0.01 and not on[:, 136:].any()
    cell = 8
    ys, xs = np.nonzero(on[64:64 + cell, 64:64 + cell])  # one cell's stroke: its main axis is the direction
    pts = np.stack([xs - xs.mean(), ys - ys.mean()])
    w, v = np.linalg.eigh(pts @ pts.T)
    got = math.degrees(math.atan2(v[1, -1], v[0, -1])) % 180.0
    assert min(abs(got - theta % 180.0), 180.0 - abs(got - theta % 180.0)) < 12.0
    assert direction_rgba(DirectionField(), n) is None
    # The Direction tool is what asks for it (H over a model); other tools leave the randomness shown.
    from types import SimpleNamespace

    from infinitex.app.ui.tools import Tool
    from infinitex.app.ui.tools.direction import DirectionTool
    key, make = DirectionTool(None).atlas_overlay(SimpleNamespace(direction=field), n)
    assert key[0] == "direction" and np.array_equal(make(), rgba)
    assert DirectionTool(None).atlas_overlay(SimpleNamespace(direction=None), n) is None
    assert Tool(None).atlas_overlay(SimpleNamespace(direction=field), n) is None
