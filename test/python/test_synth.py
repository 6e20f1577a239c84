"""Synthetic sequences: deterministic, readable by the providers, and with exact ground truth."""
from __future__ import annotations

import hashlib
import json

import cv2
import numpy as np
import pytest

from dynaorb import core
from dynaorb.synth import SynthConfig, generate


def digest(folder):
    h = hashlib.sha256()
    for p in sorted(folder.rglob("*")):
        if p.is_file() and p.name != "synth.json":
            h.update(p.name.encode())
            h.update(p.read_bytes())
    return h.hexdigest()


def test_deterministic_per_seed(tmp_path, data):
    small = dict(sensor="mono", movers=2, frames=3, width=160, height=120, fx=131.25)
    generate(tmp_path / "a", SynthConfig(seed=5, **small))
    generate(tmp_path / "b", SynthConfig(seed=5, **small))
    generate(tmp_path / "c", SynthConfig(seed=6, **small))
    assert digest(tmp_path / "a") == digest(tmp_path / "b")
    assert digest(tmp_path / "a") != digest(tmp_path / "c")


def test_frames_rendered_at_once_give_the_same_files(tmp_path, data):
    """The frames render on a thread each (one per core by default): the same images,
    labels, masks and poses as one frame at a time, for each layout."""
    small = dict(movers=3, frames=6, width=160, height=120, fx=131.25, seed=2)
    for sensor in ("mono", "stereo", "rgbd"):
        one = generate(tmp_path / f"{sensor}1", SynthConfig(sensor=sensor, **small), threads=1)
        three = generate(tmp_path / f"{sensor}3", SynthConfig(sensor=sensor, **small), threads=3)
        assert digest(tmp_path / f"{sensor}1") == digest(tmp_path / f"{sensor}3"), sensor
        assert one["path_length_m"] == three["path_length_m"]
        assert one["dynamic_pixel_fraction"] == three["dynamic_pixel_fraction"]


def test_a_failing_frame_stops_the_rendering(tmp_path, monkeypatch):
    """A frame that fails (a full disk, Ctrl-C) raises at once: the frames not started are
    cancelled, only those being rendered finish."""
    from dynaorb.synth.scene import Renderer

    calls = []
    render = Renderer.render

    def failing(self, scene, T, t):
        calls.append(t)
        if len(calls) == 3:
            raise RuntimeError("no space left on device")
        return render(self, scene, T, t)

    monkeypatch.setattr(Renderer, "render", failing)
    with pytest.raises(RuntimeError, match="no space left"):
        generate(tmp_path / "x", SynthConfig(sensor="mono", movers=0, frames=40, seed=1), threads=2)
    assert len(calls) < 20, len(calls)


def test_an_image_that_cannot_be_written_is_an_error(tmp_path, monkeypatch):
    """cv2.imwrite answers a full disk with False: generate raises, naming the file, rather
    than leaving a sequence with a frame missing."""
    write = cv2.imwrite
    monkeypatch.setattr(cv2, "imwrite", lambda path, img: False if path.endswith("labels/000003.png")
                        else write(path, img))
    with pytest.raises(OSError, match="labels/000003.png"):
        generate(tmp_path / "x", SynthConfig(sensor="mono", movers=2, frames=8, width=160, height=120,
                                             fx=131.25), threads=2)


def test_culled_boxes_render_the_same_image(data):
    """Testing each box against the rays around its projection only gives the image, depth
    and box index of testing every ray: rooms with movers (forward path) and the loop room,
    at poses along the path, with boxes beside, in front of and behind the camera."""
    import importlib

    gen = importlib.import_module("dynaorb.synth.generate")
    from dynaorb.synth.scene import Renderer

    culled_boxes = 0
    for seed, loop in ((0, False), (4, False), (1, True)):
        c = SynthConfig(sensor="mono", movers=0 if loop else 3, frames=40, seed=seed, width=320, height=240,
                        fx=262.5, path="loop" if loop else "forward")
        scene, _ = gen._scene(c)  # the scene generate() renders
        K = gen._intrinsics(c)
        culled, every = Renderer(K, c.width, c.height), Renderer(K, c.width, c.height, cull=False)
        for i in range(0, c.frames, 6):
            t = i / c.rate()
            T = scene.path.pose(t)
            for a, b in zip(culled.render(scene, T, t), every.render(scene, T, t)):
                assert np.array_equal(a, b), (seed, loop, i)
            R, o = T[:3, :3], T[:3, 3]
            culled_boxes += sum(culled._window_of(*box.corners(t), R, o) is not None for box in scene.boxes)
    assert culled_boxes > 0  # the small boxes were culled


def test_boxes_reaching_behind_the_camera_are_culled_to_what_lies_in_front(data):
    """A box with corners behind the camera is tested only against the rays around the
    projection of its part in front: the room's wall behind the camera against none, the
    floor against the rows below the horizon. Cameras 1-2 cm from the floor and from a wall,
    looking along them and into them, see those surfaces from the nearest depths a hit
    counts at, and render the image, depth and box index of testing every ray."""
    import importlib

    gen = importlib.import_module("dynaorb.synth.generate")
    from dynaorb.synth.scene import EMPTY, FLOOR_Y, ROOM_HALF_WIDTH, Renderer, camera_pose

    c = SynthConfig(sensor="mono", movers=3, frames=40, seed=2, width=160, height=120, fx=131.25)
    scene, _ = gen._scene(c)
    K = gen._intrinsics(c)
    culled, every = Renderer(K, c.width, c.height), Renderer(K, c.width, c.height, cull=False)
    box = {b.name: b for b in scene.boxes}
    t = 1.0
    T = scene.path.pose(t)
    R, o = T[:3, :3], T[:3, 3]
    assert culled._window_of(*box["wall_back"].corners(t), R, o) is EMPTY
    floor_rows, floor_cols = culled._window_of(*box["floor"].corners(t), R, o)
    assert floor_cols == slice(0, c.width)
    assert c.height // 4 < floor_rows.start < floor_rows.stop == c.height  # below the horizon (and a little above)
    ceiling_rows, _ = culled._window_of(*box["ceiling"].corners(t), R, o)
    assert ceiling_rows.start == 0 and ceiling_rows.stop < 3 * c.height // 4
    near = [camera_pose(0.0, pitch, 0.0, (0.3, FLOOR_Y - 0.01, 2.0)) for pitch in (-0.8, -0.3, 0.0)]
    near += [camera_pose(yaw, 0.0, 0.0, (-ROOM_HALF_WIDTH + 0.02, 0.5, 3.0)) for yaw in (-1.2, -0.5)]
    for T in near:
        for a, b in zip(culled.render(scene, T, t), every.render(scene, T, t)):
            assert np.array_equal(a, b)
        depth = culled.render(scene, T, t)[1]
        assert depth.min() < 0.05  # the surface next to the camera is in view


def load_rgbd(seq, i):
    provider = core().open_dataset("tum", str(seq))
    frame = provider.load(i)
    name = frame.image_path.rsplit("/", 1)[1]
    grey = cv2.cvtColor(frame.image, cv2.COLOR_BGR2GRAY).astype(np.float32)
    depth = frame.depth.astype(np.float32) / 5000.0
    dyn = cv2.imread(str(seq / "dynamic_masks" / name), cv2.IMREAD_GRAYSCALE)
    labels = cv2.imread(str(seq / "labels" / name), cv2.IMREAD_GRAYSCALE)
    return grey, depth, dyn, labels


def warp_error(seq, i, j, T_i, T_j, K):
    """Median |I_j(warp(p)) - I_i(p)| over static pixels of frame i with depth, seen in frame j."""
    gi, di, dyn_i, _ = load_rgbd(seq, i)
    gj, _, dyn_j, _ = load_rgbd(seq, j)
    h, w = gi.shape
    v, u = np.mgrid[0:h, 0:w]
    ok = (di > 0) & (dyn_i == 0)
    x = (u[ok] - K[0, 2]) / K[0, 0] * di[ok]
    y = (v[ok] - K[1, 2]) / K[1, 1] * di[ok]
    pts = np.stack([x, y, di[ok], np.ones_like(x)])
    pj = (np.linalg.inv(T_j) @ T_i @ pts)[:3]
    uj, vj = K[0, 0] * pj[0] / pj[2] + K[0, 2], K[1, 1] * pj[1] / pj[2] + K[1, 2]
    inside = (pj[2] > 0.1) & (uj > 2) & (uj < w - 3) & (vj > 2) & (vj < h - 3)
    from scipy.ndimage import map_coordinates

    coords = np.stack([vj[inside], uj[inside]])
    sampled = map_coordinates(gj, coords, order=1)
    static_j = map_coordinates(dyn_j, coords, order=0) == 0
    diff = np.abs(sampled - gi[ok][inside])[static_j]
    return float(np.median(diff)), int(diff.size)


def test_ground_truth_is_exact_photometrically(synth_rgbd):
    provider = core().open_dataset("tum", str(synth_rgbd))
    s = provider.default_settings()
    K = np.array([[s.fx, 0, s.cx], [0, s.fy, s.cy], [0, 0, 1]])
    stamps, poses = provider.ground_truth()
    assert len(stamps) == len(provider) == 8
    err, n = warp_error(synth_rgbd, 0, 6, poses[0], poses[6], K)
    assert n > 20000
    assert err < 2.0  # image noise alone (sigma 1.5 in each image) gives a median of ~1.4
    wrong = poses[6].copy()
    wrong[:3, 3] += [0.03, 0.0, 0.0]
    err_wrong, _ = warp_error(synth_rgbd, 0, 6, poses[0], wrong, K)
    assert err_wrong > 2 * err


def test_masks_and_labels(synth_rgbd):
    summary = json.loads((synth_rgbd / "synth.json").read_text())
    names = {o["name"]: o for o in summary["objects"]}
    assert names["parked_car"]["label"] == 7 and not names["parked_car"]["moving"]
    assert names["vehicle"]["moving"] and names["vehicle"]["velocity"][2] > 0  # along the camera's motion
    seen_static_car = False
    for i in range(8):
        _, _, dyn, labels = load_rgbd(synth_rgbd, i)
        assert set(np.unique(labels)) <= {0, 7, 15}
        assert np.all(labels[dyn > 0] > 0)  # every moving pixel carries a movable class
        seen_static_car |= bool(np.any((labels == 7) & (dyn == 0)))
        assert 0.05 < np.count_nonzero(dyn) / dyn.size < 0.6
    assert seen_static_car


def test_stereo_layout_and_disparity(synth_stereo):
    seq = synth_stereo / "sequences" / "00"
    provider = core().open_dataset("kitti", str(seq))
    assert provider.sensor == "stereo" and len(provider) == 6
    settings = provider.default_settings()  # settings.yaml written beside the images
    assert settings.bf == pytest.approx(262.5 * 0.12)
    stamps, poses = provider.ground_truth()
    assert len(stamps) == 6 and np.allclose(poses[0], np.eye(4))
    assert np.linalg.norm(poses[-1][:3, 3]) > 0.1
    # The right image is the left one shifted by bf / depth on static, planar parts.
    frame = provider.load(2)
    left, right = frame.image.astype(np.float32), frame.right.astype(np.float32)
    if left.ndim == 3:
        left, right = left.mean(axis=2), right.mean(axis=2)
    h, w = left.shape
    best_errs, zero_errs = [], []
    for r in range(20, h - 20, 7):
        errs = [np.mean(np.abs(left[r, 60:w - 20] - right[r, 60 - d:w - 20 - d])) for d in range(0, 40)]
        best_errs.append(min(errs))
        zero_errs.append(errs[0])
    # Rows match under a horizontal shift (rectified stereo), and not without one.
    assert np.median(best_errs) < 0.5 * np.median(zero_errs)


def test_rejects_bad_config(tmp_path):
    with pytest.raises(ValueError, match="sensor"):
        generate(tmp_path, SynthConfig(sensor="lidar"))
    with pytest.raises(ValueError, match="frames"):
        generate(tmp_path, SynthConfig(frames=1))
    with pytest.raises(FileNotFoundError):
        generate(tmp_path / "x", SynthConfig(frames=2, textures=str(tmp_path / "no_textures_here")))


def test_a_long_room_does_not_repeat_itself_and_a_short_one_is_unchanged():
    """A room slab's texture tiles every 5.7 m: down a long room its floor,
    ceiling and side walls come in pieces with textures of their own, so no place
    looks like the one a period back; a short room keeps its six slabs."""
    from dynaorb.synth.scene import LONG_ROOM_M, SEGMENT_M, build_scene
    from dynaorb.synth.textures import TextureBank

    def scene(duration: float, seed: int = 4):
        rng = np.random.default_rng(seed)
        return build_scene(TextureBank(rng, None), rng, movers=0, duration=duration, colour=False,
                           long_room_bank=TextureBank(np.random.default_rng([seed, 1]), None))

    short = scene(59 / 20)
    assert [b.name for b in short.boxes[:6]] == ["floor", "ceiling", "wall_left", "wall_right", "wall_back",
                                                "wall_front"]
    long = scene(1499 / 20)
    floor = sorted((b for b in long.boxes if b.name.startswith("floor")), key=lambda b: b.lo[2])
    length = floor[-1].hi[2] - floor[0].lo[2]
    assert length > LONG_ROOM_M and len(floor) == int(np.ceil(length / SEGMENT_M))
    assert all(b.hi[2] - b.lo[2] <= SEGMENT_M + 1e-9 for b in floor)
    np.testing.assert_allclose([b.lo[2] for b in floor[1:]], [b.hi[2] for b in floor[:-1]])  # no gaps
    textures = [b.texture[0].tobytes() for b in floor]
    assert len(set(textures)) == len(textures)
    # The furniture and every other draw come from the scene's own generator, whatever bank the pieces take.
    unsplit = [b for b in long.boxes if not any(b.name.startswith(n) for n in ("floor", "ceiling", "wall_"))]
    rng = np.random.default_rng(4)
    same = build_scene(TextureBank(rng, None), rng, movers=0, duration=1499 / 20, colour=False,
                       long_room_bank=TextureBank(np.random.default_rng(99), None))
    again = [b for b in same.boxes if not any(b.name.startswith(n) for n in ("floor", "ceiling", "wall_"))]
    assert [(b.name, b.lo.tolist(), b.texture[0].tobytes()) for b in unsplit] == \
           [(b.name, b.lo.tolist(), b.texture[0].tobytes()) for b in again]
