"""A textured room with static boxes and moving objects, ray-cast per pixel.

World ("room") frame: x right, y down, z forward (the optical convention of the
first camera, up to its offset), the floor at y = +FLOOR_Y. Every surface (the
room's six slabs included) is an axis-aligned box face, so a ray hits it by the slab method; each hit carries
texture coordinates in metres on its face, sampled from a mip pyramid.
"""
from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np

from dynaorb.synth.textures import TextureBank, pyramid

PERSON, CAR = 15, 7  # PASCAL VOC ids (what a segmentation network would output)
FLOOR_Y = 1.4        # camera height above the floor [m]
CEIL_Y = -1.6        # ceiling 3 m above the floor
ROOM_HALF_WIDTH = 4.2
# Brightness of a face by its normal axis (x: side walls, y: floor/ceiling, z: front/back).
FACE_SHADE = np.array([0.82, 1.0, 0.93], np.float32)


@dataclasses.dataclass
class Box:
    name: str
    lo: np.ndarray          # min corner at t = 0 [m]
    hi: np.ndarray          # max corner at t = 0 [m]
    texture: list           # mip pyramid (uint8 grey or BGR)
    texels_per_m: float
    label: int = 0          # VOC class id in the label image (0: background)
    velocity: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(3))
    t_start: float = -math.inf  # the object moves only between t_start and t_end
    t_end: float = math.inf

    @property
    def moving(self) -> bool:
        return bool(np.any(self.velocity != 0))

    def corners(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        d = self.velocity * float(np.clip(t, self.t_start, self.t_end))
        return self.lo + d, self.hi + d

    def moving_at(self, t: float) -> bool:
        return self.moving and self.t_start <= t <= self.t_end


def camera_pose(yaw: float, pitch: float, roll: float, position) -> np.ndarray:
    """T_room_camera (4x4) from yaw (about y), then pitch (about x), then roll (about z)."""
    r = cv2.Rodrigues(np.array([0.0, yaw, 0.0]))[0] @ cv2.Rodrigues(np.array([pitch, 0.0, 0.0]))[0] \
        @ cv2.Rodrigues(np.array([0.0, 0.0, roll]))[0]
    T = np.eye(4)
    T[:3, :3] = r
    T[:3, 3] = position
    return T


@dataclasses.dataclass
class CameraPath:
    """A smooth forward path with gentle sway, bob and head rotation."""
    speed: float = 0.8           # m/s along z
    sway: float = 0.25           # lateral amplitude [m]
    bob: float = 0.04            # vertical amplitude [m]
    yaw: float = math.radians(6)
    pitch: float = math.radians(2)
    roll: float = math.radians(1)
    z0: float = 0.0

    def pose(self, t: float) -> np.ndarray:
        """T_room_camera (4x4) at time t."""
        x = self.sway * math.sin(2 * math.pi * t / 7.0)
        y = self.bob * math.sin(2 * math.pi * t / 1.1)
        z = self.z0 + self.speed * t
        yaw = self.yaw * math.sin(2 * math.pi * t / 5.0 + 0.4)
        pitch = self.pitch * math.sin(2 * math.pi * t / 3.3)
        roll = self.roll * math.sin(2 * math.pi * t / 4.1)
        return camera_pose(yaw, pitch, roll, (x, y, z))


@dataclasses.dataclass
class LoopPath:
    """A closed circuit: an ellipse on the floor plan (x half-axis `rx`, z half-axis `rz`,
    centred at z = `zc`), one lap every `period` seconds, the camera looking along the
    direction of travel turned `outward` towards the walls, with gentle bob, pitch and roll.
    pose(t) and pose(t + period) coincide: every lap passes the same places."""
    rx: float = 2.3
    rz: float = 2.9
    zc: float = 0.0
    period: float = 12.0
    outward: float = math.radians(25)
    bob: float = 0.04
    pitch: float = math.radians(2)
    roll: float = math.radians(1)

    def pose(self, t: float) -> np.ndarray:
        """T_room_camera (4x4) at time t; starts at the near side of the ellipse heading +x."""
        th = 2 * math.pi * t / self.period
        x, z = self.rx * math.sin(th), self.zc - self.rz * math.cos(th)
        y = self.bob * math.sin(2 * math.pi * t / 1.1)
        heading = math.atan2(self.rx * math.cos(th), self.rz * math.sin(th))  # yaw of the tangent
        yaw = heading + self.outward  # travelling counter-clockwise seen from above: outward is +yaw
        pitch = self.pitch * math.sin(2 * math.pi * t / 3.3)
        roll = self.roll * math.sin(2 * math.pi * t / 4.1)
        return camera_pose(yaw, pitch, roll, (x, y, z))


@dataclasses.dataclass
class Scene:
    boxes: list
    path: CameraPath
    duration: float

    def movers(self) -> list[Box]:
        return [b for b in self.boxes if b.moving]


def textures(bank: TextureBank, colour: bool):
    """tex(size=512): the next texture of the bank as a mip pyramid, BGR or grey."""
    return lambda size=512: pyramid(bank.colour(size) if colour else bank.grey(size))


def room_slabs(tex, z_min: float, z_max: float) -> list[Box]:
    """The room between z_min and z_max: six slabs (floor, ceiling, four walls), each with its own texture."""
    W, T = ROOM_HALF_WIDTH, 0.2
    slabs = {
        "floor": ([-W, FLOOR_Y, z_min], [W, FLOOR_Y + T, z_max]),
        "ceiling": ([-W, CEIL_Y - T, z_min], [W, CEIL_Y, z_max]),
        "wall_left": ([-W - T, CEIL_Y, z_min], [-W, FLOOR_Y, z_max]),
        "wall_right": ([W, CEIL_Y, z_min], [W + T, FLOOR_Y, z_max]),
        "wall_back": ([-W, CEIL_Y, z_min - T], [W, FLOOR_Y, z_min]),
        "wall_front": ([-W, CEIL_Y, z_max], [W, FLOOR_Y, z_max + T]),
    }
    return [Box(name, np.array(lo, float), np.array(hi, float), tex(1024), texels_per_m=180.0)
            for name, (lo, hi) in slabs.items()]


# A room longer than LONG_ROOM_M has its floor, ceiling and side walls in
# pieces of SEGMENT_M along z, each with its own texture. A room slab's texture
# (1024 texels at 180 per metre) repeats every 5.7 m, and down a long room that
# period makes every place look like the one 5.7 m back: on a 1500-frame stereo
# sequence (62 m) dynaorb and ORB-SLAM3 both closed loops on it that are not
# there (ATE 15.7 / 18.2 m). Shorter rooms (a 60-frame sequence's is 14.4 m)
# are rendered as before, texel for texel: the pieces' textures come from a
# texture bank of their own, so the scene's other draws do not move.
LONG_ROOM_M = 30.0
SEGMENT_M = 5.0
_LONG_SLABS = ("floor", "ceiling", "wall_left", "wall_right")


def split_long_slabs(boxes: list[Box], tex, z_min: float, z_max: float) -> list[Box]:
    """The room's long slabs cut into SEGMENT_M pieces along z, the first keeping
    its texture, the others taking tex(1024) each; other boxes as they are."""
    edges = list(np.arange(z_min, z_max, SEGMENT_M)) + [z_max]
    out = []
    for b in boxes:
        if b.name not in _LONG_SLABS:
            out.append(b)
            continue
        for k, (a, c) in enumerate(zip(edges[:-1], edges[1:])):
            lo, hi = b.lo.copy(), b.hi.copy()
            lo[2], hi[2] = a, c
            out.append(Box(f"{b.name}_{k}", lo, hi, b.texture if k == 0 else tex(1024), b.texels_per_m))
    return out


def build_loop_scene(bank: TextureBank, rng: np.random.Generator, *, duration: float, colour: bool,
                     period: float = 12.0) -> Scene:
    """A closed room (8.4 m x 11.4 m) with furniture along all four walls and a block in
    the middle, circled by a LoopPath: the camera comes back to the places it started from."""
    tex = textures(bank, colour)
    path = LoopPath(period=period)
    W = ROOM_HALF_WIDTH
    z_min, z_max = path.zc - path.rz - 2.8, path.zc + path.rz + 2.8
    boxes = room_slabs(tex, z_min, z_max)
    # Furniture along the side walls (x = +-W) and the end walls (z = z_min, z_max), at most
    # 0.9 m deep, so that the path keeps >= 0.8 m from every surface.
    for side in (-1, 1):
        z = z_min + 0.3
        while z < z_max - 1.0:
            w, h, d = rng.uniform(0.4, 0.9), rng.uniform(0.6, 2.2), rng.uniform(0.6, 1.4)
            lo = np.array([side * W - (w if side > 0 else 0), FLOOR_Y - h, z])
            boxes.append(Box(f"furniture{len(boxes)}", lo, lo + np.array([w, h, min(d, z_max - z)]), tex(),
                             texels_per_m=260.0))
            z += d + rng.uniform(0.8, 2.0)
    for end, z_wall in ((-1, z_min), (1, z_max)):
        x = -W + 1.2
        while x < W - 1.6:
            w, h, d = rng.uniform(0.6, 1.2), rng.uniform(0.6, 2.2), rng.uniform(0.4, 0.8)
            z0 = z_wall if end < 0 else z_wall - d
            lo = np.array([x, FLOOR_Y - h, z0])
            boxes.append(Box(f"furniture{len(boxes)}", lo, lo + np.array([w, h, d]), tex(), texels_per_m=260.0))
            x += w + rng.uniform(0.8, 1.8)
    # A block in the middle of the circuit.
    boxes.append(Box("island", np.array([-0.7, FLOOR_Y - 1.1, path.zc - 1.0]),
                     np.array([0.7, FLOOR_Y, path.zc + 1.0]), tex(), texels_per_m=260.0))
    return Scene(boxes=boxes, path=path, duration=duration)


def build_scene(bank: TextureBank, rng: np.random.Generator, *, movers: int, duration: float,
                colour: bool, long_room_bank: TextureBank | None = None) -> Scene:
    """The room, static furniture, a parked car, and `movers` moving objects.

    Mover 0 is a person crossing; mover 1 a vehicle travelling beside the camera
    in its direction of motion (its points satisfy the epipolar constraint);
    further movers are more people crossing at other times and distances.
    long_room_bank: where a long room's slab pieces take their textures
    (split_long_slabs; default: `bank`).
    """
    tex = textures(bank, colour)
    path = CameraPath()
    length = path.speed * duration
    z_min, z_max = -3.0, length + 9.0
    boxes = room_slabs(tex, z_min, z_max)
    if z_max - z_min > LONG_ROOM_M:
        boxes = split_long_slabs(boxes, textures(long_room_bank or bank, colour), z_min, z_max)
    # Static furniture along the walls (depth structure for the tracker).
    z = 1.0
    while z < z_max - 2.0:
        side = -1 if rng.random() < 0.5 else 1
        w, h, d = rng.uniform(0.5, 1.0), rng.uniform(0.6, 2.2), rng.uniform(0.6, 1.6)
        x_wall = side * ROOM_HALF_WIDTH
        lo = np.array([x_wall - (w if side > 0 else 0), FLOOR_Y - h, z])
        boxes.append(Box(f"furniture{len(boxes)}", lo, lo + np.array([w, h, d]), tex(), texels_per_m=260.0))
        z += d + rng.uniform(1.0, 3.0)
    # A parked car: a movable class that does not move.
    zc = 0.45 * length + 4.0
    boxes.append(Box("parked_car", np.array([-3.6, FLOOR_Y - 1.4, zc]), np.array([-1.9, FLOOR_Y, zc + 3.8]),
                     tex(), texels_per_m=200.0, label=CAR))

    people = [i for i in range(movers) if i != 1]
    for k, i in enumerate(people):
        # Crossing the camera's path around time tc, ahead of the camera by `ahead` metres.
        tc = duration * (k + 0.5) / max(len(people), 1)
        ahead = rng.uniform(2.2, 3.2)
        speed = rng.uniform(0.9, 1.4) * (1 if k % 2 == 0 else -1)
        w, h, d = 0.55, 1.75, 0.35
        cz = path.pose(tc)[2, 3] + ahead
        cx0 = path.pose(tc)[0, 3] - speed * tc  # at x = camera x at tc
        lo = np.array([cx0 - w / 2, FLOOR_Y - h, cz - d / 2])
        boxes.append(Box(f"person{i}", lo, lo + np.array([w, h, d]), tex(256), texels_per_m=300.0,
                         label=PERSON, velocity=np.array([speed, 0.0, 0.0]),
                         t_start=0.0, t_end=duration))
    if movers >= 2:
        # A vehicle to the right, driving the camera's way slightly faster.
        v = path.speed * 1.15
        lo = np.array([0.9, FLOOR_Y - 1.45, 2.0])
        boxes.append(Box("vehicle", lo, lo + np.array([1.7, 1.45, 3.9]), tex(), texels_per_m=220.0,
                         label=CAR, velocity=np.array([0.0, 0.0, v]), t_start=0.0, t_end=duration))
    return Scene(boxes=boxes, path=path, duration=duration)


def _sample(tex: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Bilinear texture lookup at (x, y) with wrap-around (cv2.remap on a 2-D map,
    as remap takes at most 32767 rows)."""
    n, cols = x.size, 1024
    rows = -(-n // cols)
    mx = np.zeros(rows * cols, np.float32)
    my = np.zeros(rows * cols, np.float32)
    mx[:n], my[:n] = x, y
    out = cv2.remap(tex, mx.reshape(rows, cols), my.reshape(rows, cols), cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_WRAP)
    return out.reshape(rows * cols, -1)[:n].astype(np.float32)


# Culling (Renderer._window_of): the camera depth the box is clipped at, half the
# smallest depth render counts as a hit (1e-3 m), and the box's 12 edges as pairs of
# corner indices (corner 4 i + 2 j + l has x from i, y from j, z from l).
NEAR_CLIP = 5e-4
_BOX_EDGES = [(k, k + step) for step in (4, 2, 1) for k in range(8) if not k & step]
EMPTY = (slice(0, 0), slice(0, 0))  # _window_of: no pixel


class Renderer:
    """Pinhole ray caster for one image size and intrinsics. cull: each box is tested
    against the rays of the pixels around the projection of its part in front of the
    camera only (_window_of: the same image as testing every ray, faster where boxes are
    small in view or reach behind the camera)."""

    def __init__(self, K: np.ndarray, width: int, height: int, cull: bool = True):
        self.K, self.width, self.height, self.cull = K, width, height, cull
        u, v = np.meshgrid(np.arange(width, dtype=np.float64) + 0.0, np.arange(height, dtype=np.float64))
        rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], -1)
        self.rays = rays.reshape(-1, 3)  # z = 1: the ray parameter t is the depth
        self.ray_len = np.linalg.norm(self.rays, axis=1)

    def _window_of(self, lo: np.ndarray, hi: np.ndarray, R: np.ndarray, o: np.ndarray):
        """The pixels whose rays may hit the box [lo, hi] (room frame) seen from the camera
        (R, o), as (row slice, column slice) of the image; None: every pixel; EMPTY: none.

        A hit counts only at a depth t > 1e-3 (render), so it lies in the part of the box at
        camera depth >= NEAR_CLIP: the box clipped by that plane, a convex polytope whose
        vertices are the corners in front of it and the points where the box's edges cross
        it. Projection keeps convexity in front of the camera, so every hit's pixel lies in
        the rectangle around the vertices' projections, here 2 px wider on every side. A
        box wholly behind the plane has no pixel: the room's wall behind the camera is not
        tested at all, the floor only below the horizon."""
        if not self.cull:
            return None
        xs, ys, zs = (lo[0], hi[0]), (lo[1], hi[1]), (lo[2], hi[2])
        corners = np.array([[x, y, z] for x in xs for y in ys for z in zs])
        cam = (corners - o) @ R  # R^T (X - o), one corner a row; corner k = 4 i + 2 j + l
        z = cam[:, 2]
        front = z >= NEAR_CLIP
        if not front.any():
            return EMPTY
        vertices = [cam[front]]
        if not front.all():
            a, b = np.array(_BOX_EDGES).T
            cross = front[a] != front[b]
            a, b = a[cross], b[cross]
            s = ((NEAR_CLIP - z[a]) / (z[b] - z[a]))[:, None]
            vertices.append(cam[a] + s * (cam[b] - cam[a]))
        p = np.concatenate(vertices)
        K = self.K
        u = K[0, 0] * p[:, 0] / p[:, 2] + K[0, 2]
        v = K[1, 1] * p[:, 1] / p[:, 2] + K[1, 2]
        # np.clip first: a vertex on the near plane can project 1e6 px away.
        c0 = int(np.floor(np.clip(u.min(), -4.0, self.width + 4.0))) - 2
        c1 = int(np.ceil(np.clip(u.max(), -4.0, self.width + 4.0))) + 2
        r0 = int(np.floor(np.clip(v.min(), -4.0, self.height + 4.0))) - 2
        r1 = int(np.ceil(np.clip(v.max(), -4.0, self.height + 4.0))) + 2
        c0, c1, r0, r1 = max(c0, 0), min(c1, self.width - 1), max(r0, 0), min(r1, self.height - 1)
        if c0 > c1 or r0 > r1:
            return EMPTY
        if (c1 - c0 + 1) * (r1 - r0 + 1) == self.width * self.height:
            return None
        return slice(r0, r1 + 1), slice(c0, c1 + 1)

    def render(self, scene: Scene, T_room_cam: np.ndarray, t: float):
        """(image uint8, depth float32 metres, box index int16 per pixel)."""
        R, o = T_room_cam[:3, :3], T_room_cam[:3, 3]
        d = R @ self.rays.T  # (3, N): one contiguous row per axis
        d = np.where(np.abs(d) < 1e-12, 1e-12, d)
        inv = 1.0 / d
        n = d.shape[1]
        best_t = np.full(n, np.inf)
        best_box = np.full(n, -1, np.int16)
        best_axis = np.zeros(n, np.int8)
        shape = (self.height, self.width)
        inv_image, best_t_image = inv.reshape((3,) + shape), best_t.reshape(shape)  # views
        for index, box in enumerate(scene.boxes):
            lo, hi = box.corners(t)
            # Only the pixels whose rays can reach the box, a window of the image (views,
            # no copies): the same per-pixel arithmetic on fewer pixels, so the same image.
            window = self._window_of(lo, hi, R, o)
            if window is EMPTY:
                continue
            rows, cols = window or (slice(0, self.height), slice(0, self.width))
            inv_p = inv_image[:, rows, cols]
            t1, t2 = (lo - o)[:, None, None] * inv_p, (hi - o)[:, None, None] * inv_p
            tnear, tfar = np.minimum(t1, t2), np.maximum(t1, t2)
            hit_t = np.maximum(np.maximum(tnear[0], tnear[1]), tnear[2])
            exit_t = np.minimum(np.minimum(tfar[0], tfar[1]), tfar[2])
            y, x = np.nonzero((hit_t <= exit_t) & (hit_t > 1e-3) & (hit_t < best_t_image[rows, cols]))
            closer = (y + rows.start) * self.width + (x + cols.start)
            best_t[closer] = hit_t[y, x]
            best_box[closer] = index
            best_axis[closer] = np.argmax(tnear[:, y, x], axis=0)  # the face the ray enters
        d = d.T
        points = o + d * best_t[:, None]
        channels = scene.boxes[0].texture[0].ndim == 3
        image = np.zeros((n, 3) if channels else n, np.float32)
        # Pixel footprint on the surface, in metres, for the mip level.
        cos = np.abs(d[np.arange(n), best_axis]) / np.linalg.norm(d, axis=1)
        footprint = best_t * self.ray_len / self.K[0, 0] / np.maximum(cos, 0.05)
        for index, box in enumerate(scene.boxes):
            sel = np.nonzero(best_box == index)[0]
            if sel.size == 0:
                continue
            lo, _ = box.corners(t)
            local = points[sel] - lo
            axis = best_axis[sel]
            # Face coordinates: x-faces (z, y), y-faces (x, z), z-faces (x, y).
            u = np.where(axis == 0, local[:, 2], local[:, 0])
            v = np.where(axis == 1, local[:, 2], local[:, 1])
            level = np.clip(np.floor(np.log2(np.maximum(footprint[sel] * box.texels_per_m, 1.0))), 0,
                            len(box.texture) - 1).astype(int)
            for lv in np.unique(level):
                m = level == lv
                tex = box.texture[lv]
                scale = box.texels_per_m / 2 ** lv
                th, tw = tex.shape[:2]
                sample = _sample(tex, np.mod(u[m] * scale, tw), np.mod(v[m] * scale, th))
                image[sel[m]] = sample.reshape(image[sel[m]].shape)
            shade = FACE_SHADE[axis]
            image[sel] *= shade[:, None] if channels else shade
        image = image.reshape(shape + ((3,) if channels else ()))
        depth = best_t.reshape(shape).astype(np.float32)
        return image, depth, best_box.reshape(shape)
