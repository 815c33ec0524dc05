"""Matterport-like capture: tripod positions in free space, 3 tilts × 6 yaws per position, pinhole cameras.

Conventions are the workspace's (ingest/src/camera.rs): camera-to-world in the OpenGL camera frame (looks
along −z, +y up, +x right), pixel centres at integer coordinates, the ray through pixel (u, v) is
((u − cx)/fx, −(v − cy)/fy, −1) in camera coordinates. Poses live in the z-up scan frame; `UP_ROTATIONS`
(convert.py) maps them back into the Mitsuba scene's own frame for rendering and ray casting.

A tripod position is accepted when it stands in free space: its eye is 1.4–1.6 m above a floor found by a
downward ray, and among `FREE_RAYS` rays in all directions none hits within `MIN_CLEARANCE`, few escape the
scene and few hit the back of a surface (a camera inside a closed piece of furniture sees back-faces). From
the accepted candidates, positions are chosen farthest-point first, so that a scan spreads over the interior
(`sample_positions`), or, for scenes of many rooms, each where its panorama sees the most surface the others
have not (`cover_positions`), as a scan operator places a tripod in every room.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

TILTS_DEG = (-35.0, 0.0, 35.0)  # Matterport's three cameras look down, level and up; ±35° with a 50° vertical
# field of view leaves no gap between the three rows
YAWS = 6  # six yaws 60° apart: with a 60° horizontal field of view the row closes the circle
FREE_RAYS = 96  # directions probed around a candidate eye (Fibonacci sphere)
MIN_CLEARANCE = 0.3  # metres: a tripod needs this much room around the camera head
MAX_MISS_FRACTION = 0.15  # rays escaping the scene: the candidate is outside the building or sees through a gap
MAX_BACKFACE_FRACTION = 0.2  # rays hitting a surface from behind: the candidate is inside furniture or a wall
EYE_HEIGHT = (1.4, 1.6)  # metres above the floor below the tripod
MAX_FLOOR_DROP = 4.0  # metres: a candidate with no floor this close below is above a void


@dataclass
class Camera:
    name: str
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    cam_to_world: np.ndarray  # 4×4 in the scan frame, OpenGL camera


def intrinsics(width: int, height: int, hfov_deg: float) -> tuple[float, float, float, float]:
    """fx = fy from the horizontal field of view, principal point at the image centre (pixel centres at
    integers: the centre of a W-pixel row is (W − 1)/2)."""
    f = 0.5 * width / math.tan(math.radians(hfov_deg) / 2.0)
    return f, f, (width - 1) / 2.0, (height - 1) / 2.0


def yaw_tilt_pose(eye: np.ndarray, yaw: float, tilt: float) -> np.ndarray:
    """Camera-to-world of a camera at `eye` looking at azimuth `yaw` (radians, from +x toward +y) and
    elevation `tilt` (radians, up positive), level horizon, z up."""
    fwd = np.array([math.cos(tilt) * math.cos(yaw), math.cos(tilt) * math.sin(yaw), math.sin(tilt)])
    right = np.array([math.sin(yaw), -math.cos(yaw), 0.0])
    up = np.cross(right, fwd)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, up, -fwd, eye
    return m


def pixel_rays(cam: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Origins and unit directions (scan frame) of the pixel-centre rays, row-major (v, then u)."""
    v, u = np.mgrid[0 : cam.height, 0 : cam.width].astype(np.float64)
    d = np.stack([(u - cam.cx) / cam.fx, -(v - cam.cy) / cam.fy, -np.ones_like(u)], -1).reshape(-1, 3)
    d = d @ cam.cam_to_world[:3, :3].T
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return np.tile(cam.cam_to_world[:3, 3], (len(d), 1)), d


def fibonacci_sphere(n: int) -> np.ndarray:
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = math.pi * (1.0 + math.sqrt(5.0)) * i
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)


class FreeSpace:
    """Ray queries against a Mitsuba scene, in the scan frame."""

    def __init__(self, scene, rot: np.ndarray, mi):
        self.scene, self.rot, self.mi = scene, rot, mi

    def hits(self, origins: np.ndarray, dirs: np.ndarray):
        """(distance or inf, cosine between the ray and the surface's shading normal) in the scan frame."""
        from .convert import cast

        si = cast(self.scene, origins @ self.rot, dirs @ self.rot, self.mi)
        valid = np.array(si.is_valid(), dtype=bool)
        t = np.where(valid, np.array(si.t, dtype=np.float64), np.inf)
        n = np.array(si.sh_frame.n, dtype=np.float64).T @ self.rot.T
        cos = np.einsum("ij,ij->i", n, dirs)
        return t, cos

    def eye_above_floor(self, starts: np.ndarray, rng) -> np.ndarray:
        """One eye per start point (NaN rows where none): 1.4–1.6 m above the first surface below it. The
        surface's orientation is not checked (scenes wind floors either way); `is_free` rejects bad eyes."""
        d = np.tile([0.0, 0.0, -1.0], (len(starts), 1))
        t, _ = self.hits(starts, d)
        ok = np.isfinite(t) & (t < MAX_FLOOR_DROP)
        eye = starts.copy()
        eye[:, 2] = starts[:, 2] - t + rng.uniform(*EYE_HEIGHT, size=len(starts))
        eye[~ok] = np.nan
        return eye

    def free_mask(self, eyes: np.ndarray) -> np.ndarray:
        """Per eye: True when it stands in free space (module docs), all eyes in one batch of rays."""
        if len(eyes) == 0:
            return np.zeros(0, bool)
        dirs = fibonacci_sphere(FREE_RAYS)
        o = np.repeat(eyes, len(dirs), axis=0)
        t, cos = self.hits(o, np.tile(dirs, (len(eyes), 1)))
        t, cos = t.reshape(len(eyes), -1), cos.reshape(len(eyes), -1)
        near = np.any(t < MIN_CLEARANCE, axis=1)
        miss = np.mean(~np.isfinite(t), axis=1) > MAX_MISS_FRACTION
        back = np.mean(np.isfinite(t) & (cos > 0), axis=1) > MAX_BACKFACE_FRACTION
        return ~(near | miss | back)


def candidate_eyes(space: FreeSpace, bbox: np.ndarray, rng, candidates: int = 400) -> np.ndarray:
    """Tripod eyes in free space inside `bbox` (2×3, scan frame), from `candidates` random start points."""
    lo, hi = bbox
    # Start points at random heights, so that every storey of a multi-level scene gets candidates.
    starts = rng.uniform(lo, hi, size=(candidates, 3))
    eyes = space.eye_above_floor(starts, rng)
    eyes = eyes[~np.isnan(eyes[:, 0])]
    eyes = eyes[eyes[:, 2] < hi[2] - MIN_CLEARANCE]
    return eyes[space.free_mask(eyes)]


def sample_positions(space: FreeSpace, bbox: np.ndarray, count: int, rng, exclude=(), candidates: int = 400):
    """`count` tripod eyes in free space inside `bbox` (2×3, scan frame), chosen farthest-point first from
    `candidates` random candidates (and away from the eyes in `exclude`)."""
    pool = candidate_eyes(space, bbox, rng, candidates)
    if len(pool) == 0:
        return pool
    dist = None
    if len(exclude):
        dist = np.min([np.linalg.norm(pool - np.asarray(e), axis=1) for e in exclude], axis=0)
    chosen = []
    while len(chosen) < min(count, len(pool)):
        # The first pick is the candidate nearest the pool's centroid (unless `exclude` sets distances).
        k = int(np.argmin(np.linalg.norm(pool - pool.mean(0), axis=1))) if dist is None else int(np.argmax(dist))
        chosen.append(pool[k])
        d = np.linalg.norm(pool - pool[k], axis=1)
        dist = d if dist is None else np.minimum(dist, d)
    return np.array(chosen)


COVER_RAYS = 2048  # directions probed from a candidate eye when counting what its panorama sees
COVER_CELL = 0.25  # metres: the seen surface is counted in cubes of this size
COVER_RANGE = 3.0  # metres: surface counts as scanned from an eye this close (Matterport's guidance puts
# tripods about 2.5 m apart; its depth camera reaches 4.5 m, from which a room seen through a door counted as
# covered and the house's central room got no tripod)
# The panorama's three rows (tilts ±35°, 50° vertical field of view) see elevations up to ±60°.
COVER_MAX_ELEVATION_DEG = 60.0


def seen_cells(space: FreeSpace, eyes: np.ndarray) -> list[set]:
    """Per eye, the COVER_CELL cubes of surface that rays from it within the panorama's elevations hit within
    COVER_RANGE."""
    dirs = fibonacci_sphere(COVER_RAYS)
    dirs = dirs[np.abs(dirs[:, 2]) <= math.sin(math.radians(COVER_MAX_ELEVATION_DEG))]
    t, _ = space.hits(np.repeat(eyes, len(dirs), axis=0), np.tile(dirs, (len(eyes), 1)))
    t = t.reshape(len(eyes), -1)
    out = []
    for eye, te in zip(eyes, t):
        ok = te <= COVER_RANGE
        p = eye + te[ok, None] * dirs[ok]
        out.append(set(map(tuple, np.floor(p / COVER_CELL).astype(np.int64).tolist())))
    return out


def cover_positions(space: FreeSpace, bbox: np.ndarray, count: int, rng, candidates: int = 1000):
    """`count` tripod eyes chosen as a scan operator places them: each next one where its panorama sees the
    most surface that the ones before it have not (greedy coverage of `seen_cells`; ties go to the candidate
    farthest from the eyes chosen). A room no tripod stands in is mostly unscanned, so the greedy choice goes
    from room to room: on the house's 12 rooms, 12 positions stood one in each room for each of ten candidate
    draws tried, where farthest-point placement at 10 positions left two rooms without one (and their lights
    and objects seen only through doors)."""
    pool = candidate_eyes(space, bbox, rng, candidates)
    if len(pool) == 0:
        return pool
    cells = seen_cells(space, pool)
    covered: set = set()
    dist = np.full(len(pool), np.inf)
    chosen = []
    while len(chosen) < min(count, len(pool)):
        gain = np.array([len(c - covered) for c in cells], dtype=np.float64)
        k = int(np.lexsort((-dist, -gain))[0])
        chosen.append(pool[k])
        covered |= cells[k]
        dist = np.minimum(dist, np.linalg.norm(pool - pool[k], axis=1))
    return np.array(chosen)


def panorama(prefix: str, eye, width: int, height: int, hfov_deg: float, yaw0: float) -> list[Camera]:
    """The 18 views of one tripod position, named `<prefix>_i<tilt>_<yaw>` (Matterport's pattern)."""
    fx, fy, cx, cy = intrinsics(width, height, hfov_deg)
    views = []
    for i, tilt in enumerate(TILTS_DEG):
        for j in range(YAWS):
            pose = yaw_tilt_pose(np.asarray(eye, float), yaw0 + 2 * math.pi * j / YAWS, math.radians(tilt))
            views.append(Camera(f"{prefix}_i{i}_{j}", width, height, fx, fy, cx, cy, pose))
    return views


def conf_text(cameras: list[Camera]) -> str:
    """A Matterport `.conf`: one `intrinsics_matrix` line before each run of cameras sharing it, one `scan`
    line per camera with its camera-to-world, row-major."""
    s = (
        f"dataset matterport\nn_images {len(cameras)}\ndepth_directory undistorted_depth_images\n"
        "color_directory undistorted_color_images\n"
    )
    last = None
    for c in cameras:
        k = (c.fx, c.fy, c.cx, c.cy)
        if k != last:
            s += f"intrinsics_matrix {c.fx!r} 0 {c.cx!r}  0 {c.fy!r} {c.cy!r} 0 0 1\n"
            last = k
        s += f"scan {c.name.replace('_i', '_d', 1)}.png {c.name}.exr " + " ".join(
            repr(float(x)) for x in c.cam_to_world.ravel()
        ) + "\n"
    return s


def read_conf(path) -> list[Camera]:
    """Cameras of a `.conf` written by `conf_text` (sizes are filled in by the caller)."""
    cams, k = [], None
    for line in open(path):
        tok = line.split()
        if not tok:
            continue
        if tok[0] == "intrinsics_matrix":
            m = [float(t) for t in tok[1:10]]
            k = (m[0], m[4], m[2], m[5])
        elif tok[0] == "scan":
            pose = np.array([float(t) for t in tok[3:19]]).reshape(4, 4)
            cams.append(Camera(tok[2].rsplit(".", 1)[0], 0, 0, *k, pose))
    return cams
