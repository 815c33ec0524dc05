"""Procedural interiors as Mitsuba 3 XML: rooms on a grid joined by doors, furniture, lights, windows, sky.

One generator serves every synthetic scene of the corpus; a scene is a `HouseSpec` (a parameter set):

- Rooms are the cells of an `nx × ny` grid (column widths, row depths, one ceiling height). Every room has a
  floor (facing up) and a ceiling (facing down); walls run along the grid lines, one object per room side,
  exterior walls facing inwards, interior walls shared by the two rooms they separate. Neighbouring rooms are
  joined by doors (holes in the shared wall) along a random spanning tree, so the whole house is connected.
- Windows are holes in exterior walls, each closed by a *pane*: a rectangle with a `null` BSDF whose normal
  points indoors. The scan converter (scan.py) keeps panes as emitters and leaves them out of the photos.
- Furniture: closed boxes (outward winding) tessellated `n × n` per face, plus tall cabinets whose top is a
  tray (a 6 cm rim) that may hold a hidden uplight: a light facing up at 1.95 m cannot be seen from a camera
  at 1.4–1.6 m, so it lights the room only through the ceiling. Decor spheres (icospheres) add triangles.
- Lights: ceiling panels (`rectangle` shapes facing down, a chosen colour) and hidden uplights.
- Materials: diffuse, rough plastic or rough conductor, either uniform or textured with a procedural PNG
  (checker, stripes, planks, noise) through UVs in metres, so textures scale with the surface.
- Daylight: an `envmap` sky (a lat-long EXR: bright horizon, blue zenith, dark ground) or a `constant` one.

The output is a directory with `scene.xml`, `meshes/*.ply` and `textures/*`; the same spec and seed give
the same bytes. Coordinates are metres, z up (no rotation needed when converting).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

WALL_COLOURS = [(0.75, 0.72, 0.66), (0.62, 0.68, 0.74), (0.78, 0.62, 0.52), (0.58, 0.70, 0.58), (0.85, 0.84, 0.80)]
FURNITURE_COLOURS = [(0.60, 0.60, 0.20), (0.25, 0.50, 0.60), (0.55, 0.25, 0.22), (0.30, 0.30, 0.32),
                     (0.70, 0.55, 0.35), (0.20, 0.35, 0.25), (0.80, 0.78, 0.70)]
LIGHT_COLOURS = {"warm": (20.0, 15.0, 9.0), "cool": (12.0, 15.0, 20.0), "white": (16.0, 16.0, 16.0),
                 "orange": (22.0, 11.0, 4.0), "green": (8.0, 18.0, 9.0)}
TRAY_RIM = 0.06  # metres: rim around a cabinet top; hides an uplight from every camera below the rim's top
FREE_RADIUS = 0.6  # metres of free floor around each room centre: room for a tripod with 0.3 m clearance
UPLIGHT_GAP = 0.005  # metres between the cabinet top and its uplight: no z-fighting in float32


@dataclass
class Material:
    kind: str = "diffuse"  # diffuse | plastic | metal
    color: tuple = (0.7, 0.7, 0.7)
    texture: str | None = None  # checker | stripes | planks | noise
    color2: tuple = (0.2, 0.2, 0.2)
    tile: float = 0.5  # metres per texture repeat
    roughness: float = 0.3  # Disney roughness (α = roughness²) of plastic and metal


@dataclass
class HouseSpec:
    name: str = "room"
    seed: int = 0
    columns: tuple = (3.0,)  # room widths along x, metres
    rows: tuple = (2.5,)  # room depths along y
    height: float = 2.2
    furniture_per_room: tuple = (1, 2)  # (min, max) boxes besides cabinets
    cabinets_per_room: int = 1
    spheres_per_room: int = 0
    box_tessellation: int = 2  # cells per box face side
    sphere_subdivisions: int = 2
    surface_tessellation: int = 4  # cells per side of floors and ceilings
    textured_fraction: float = 0.5  # share of furniture and walls that get a texture
    floor_texture: str | None = "planks"
    metal_fraction: float = 0.0  # share of furniture boxes in rough metal
    plastic_fraction: float = 0.0  # share in rough plastic
    ceiling_lights: tuple = ("warm",)  # colour of the ceiling panel per room (cycled); "" for none
    light_size: tuple = (0.6, 0.4)
    uplights: tuple = ()  # colours of hidden uplights, placed on cabinets of rooms 0, 1, ... (cycled)
    windows_per_exterior_wall: float = 0.0  # mean number of windows per exterior wall
    window_size: tuple = (1.0, 1.0)
    window_sill: float = 0.9
    sky: str | None = None  # None | "envmap" | "constant"
    sky_radiance: tuple = (2.0, 2.2, 2.6)
    door_size: tuple = (0.9, 2.0)
    extra_doors: float = 0.3  # chance that a neighbouring pair outside the spanning tree also gets a door


@dataclass
class Obj:
    name: str
    material: Material | None
    pos: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    uv: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    tri: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), int))

    def add(self, pos, uv, tri):
        tri = np.asarray(tri) + len(self.pos)
        self.pos = np.concatenate([self.pos, pos])
        self.uv = np.concatenate([self.uv, uv])
        self.tri = np.concatenate([self.tri, tri]).astype(int)


def grid_quad(origin, u, v, nu: int, nv: int, uv_scale: float = 1.0):
    """A parallelogram origin + s·u + t·v cut into nu × nv cells, wound so that u × v is the front side;
    UVs are in metres along u and v divided by `uv_scale`."""
    origin, u, v = (np.asarray(x, float) for x in (origin, u, v))
    s, t = np.meshgrid(np.linspace(0, 1, nu + 1), np.linspace(0, 1, nv + 1), indexing="ij")
    pos = origin + s.reshape(-1, 1) * u + t.reshape(-1, 1) * v
    uv = np.stack([s.ravel() * np.linalg.norm(u), t.ravel() * np.linalg.norm(v)], 1) / uv_scale
    idx = lambda i, j: i * (nv + 1) + j  # noqa: E731
    tri = []
    for i in range(nu):
        for j in range(nv):
            a, b, c, d = idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)
            tri += [[a, b, c], [a, c, d]]
    return pos, uv, np.array(tri)


def wall_with_holes(a, b, height, holes, inward, uv_scale):
    """A vertical wall from a to b (floor points), holes as (s0, s1, z0, z1) along it, front side `inward`:
    the wall rectangle cut on every hole edge, cells inside a hole left out."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    length = np.linalg.norm(b - a)
    ss = sorted({0.0, length, *[h[0] for h in holes], *[h[1] for h in holes]})
    zs = sorted({0.0, height, *[h[2] for h in holes], *[h[3] for h in holes]})
    along = (b - a) / length
    up = np.array([0.0, 0.0, 1.0])
    flip = np.dot(np.cross(along, up), inward) < 0
    pos, uv, tri = [], [], []
    for s0, s1 in zip(ss, ss[1:]):
        for z0, z1 in zip(zs, zs[1:]):
            sm, zm = (s0 + s1) / 2, (z0 + z1) / 2
            if any(h[0] < sm < h[1] and h[2] < zm < h[3] for h in holes):
                continue
            o = a + s0 * along + z0 * up
            u, v = (s1 - s0) * along, (z1 - z0) * up
            p, t, f = grid_quad(o, u, v, 1, 1)
            t = (np.array([[s0, z0], [s0, z1], [s1, z0], [s1, z1]])) / uv_scale
            if flip:
                f = f[:, [0, 2, 1]]
            tri.append(f + sum(len(x) for x in pos))
            pos.append(p)
            uv.append(t)
    return np.concatenate(pos), np.concatenate(uv), np.concatenate(tri)


def box(lo, hi, n: int, uv_scale: float, tray: float = 0.0):
    """A closed box (outward winding) with n × n cells per face; `tray` > 0 adds a rim of that height around
    the top (both sides of the rim, so the tray is closed to the eye from below)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    d = hi - lo
    ex, ey, ez = np.diag(d)
    faces = [
        (lo, ey, ex), (lo + ez, ex, ey),  # bottom (−z), top (+z)
        (lo, ex, ez), (lo + ey, ez, ex),  # −y, +y
        (lo, ez, ey), (lo + ex, ey, ez),  # −x, +x
    ]
    o = Obj("", None)
    for origin, u, v in faces:
        o.add(*grid_quad(origin, u, v, n, n, uv_scale))
    if tray > 0:
        top = lo + ez
        rz = np.array([0, 0, tray])
        for origin, u in [(top, ex), (top + ex, ey), (top + ex + ey, -ex), (top + ey, -ey)]:
            o.add(*grid_quad(origin, u, rz, 1, 1, uv_scale))  # outside of the rim
            o.add(*grid_quad(origin, rz, u, 1, 1, uv_scale))  # inside
    return o.pos, o.uv, o.tri


def icosphere(center, radius, subdivisions: int):
    t = (1 + 5**0.5) / 2
    v = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
         [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
         [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11],
         [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    v = [np.array(x, float) / np.linalg.norm(x) for x in v]
    for _ in range(subdivisions):
        cache, nf = {}, []

        def mid(i, j):
            key = (min(i, j), max(i, j))
            if key not in cache:
                m = v[i] + v[j]
                v.append(m / np.linalg.norm(m))
                cache[key] = len(v) - 1
            return cache[key]

        for a, b, c in f:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            nf += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        f = nf
    p = np.array(v)
    uv = np.stack([0.5 + np.arctan2(p[:, 1], p[:, 0]) / (2 * np.pi), 0.5 + np.arcsin(p[:, 2]) / np.pi], 1)
    return p * radius + np.asarray(center, float), uv, np.array(f)


# ---------------------------------------------------------------------------------------------- textures
def texture_image(kind: str, c1, c2, rng, size: int = 128) -> np.ndarray:
    """An sRGB-encoded uint8 (size, size, 3) tile of a procedural pattern between linear colours c1 and c2."""
    y, x = np.mgrid[0:size, 0:size] / size
    if kind == "checker":
        w = ((np.floor(x * 2) + np.floor(y * 2)) % 2)[..., None]
    elif kind == "stripes":
        w = (np.floor(x * 6) % 2)[..., None] * 0.8 + 0.1
    elif kind == "planks":
        row = np.floor(y * 4)
        shift = rng.random(4)[row.astype(int)]
        grain = 0.5 + 0.5 * np.sin(40 * y + 6 * np.sin(8 * (x + shift)))
        seam = ((y * 4) % 1 < 0.04) | (((x + shift) * 2) % 1 < 0.01)
        w = (0.25 + 0.5 * grain * (0.6 + 0.4 * rng.random(4)[row.astype(int)]))
        w = np.where(seam, 1.0, w)[..., None]
    else:  # noise: smooth value noise, periodic over the tile
        g = rng.random((8, 8))
        xi, yi = x * 8, y * 8
        i0, j0 = np.floor(xi).astype(int) % 8, np.floor(yi).astype(int) % 8
        fx, fy = xi - np.floor(xi), yi - np.floor(yi)
        sx, sy = fx * fx * (3 - 2 * fx), fy * fy * (3 - 2 * fy)
        top = g[j0, i0] * (1 - sx) + g[j0, (i0 + 1) % 8] * sx
        bot = g[(j0 + 1) % 8, i0] * (1 - sx) + g[(j0 + 1) % 8, (i0 + 1) % 8] * sx
        w = (top * (1 - sy) + bot * sy)[..., None]
    lin = np.asarray(c1) * (1 - w) + np.asarray(c2) * w
    srgb = np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * np.power(np.clip(lin, 0, 1), 1 / 2.4) - 0.055)
    return np.round(np.clip(srgb, 0, 1) * 255).astype(np.uint8)


def write_png(path: Path, rgb8: np.ndarray) -> None:
    import mitsuba as mi

    mi.Bitmap(np.ascontiguousarray(rgb8), pixel_format=mi.Bitmap.PixelFormat.RGB).write(str(path))


def sky_image(radiance, width: int = 128) -> np.ndarray:
    """Lat-long sky in Mitsuba's envmap frame (+y up): horizon `radiance`, zenith bluer and darker, ground a
    dim brown (0.3 of the horizon)."""
    h = width // 2
    theta = (np.arange(h) + 0.5) / h * np.pi  # 0 at +y (zenith)
    elev = np.pi / 2 - theta
    r = np.asarray(radiance, float)
    zen = r * np.array([0.45, 0.6, 1.0])
    sky = np.where(elev[:, None] >= 0, r * (1 - np.sin(np.maximum(elev, 0)))[:, None]
                   + zen * np.sin(np.maximum(elev, 0))[:, None], 0.3 * r * np.array([0.9, 0.75, 0.55]))
    return np.repeat(sky[:, None, :], width, axis=1).astype(np.float32)


# ---------------------------------------------------------------------------------------------- the house
@dataclass
class Light:
    name: str
    center: np.ndarray
    size: tuple
    normal_up: bool
    radiance: tuple


@dataclass
class Pane:
    name: str
    center: np.ndarray
    along: np.ndarray  # unit, horizontal
    size: tuple  # (width, height)
    inward: np.ndarray


def _material_xml(m: Material, tex_name: str | None) -> str:
    def colour(name):
        if tex_name:
            return (f'<texture type="bitmap" name="{name}"><string name="filename" value="textures/{tex_name}.png"/>'
                    f'<string name="filter_type" value="bilinear"/></texture>')
        return f'<rgb name="{name}" value="{m.color[0]:.4f}, {m.color[1]:.4f}, {m.color[2]:.4f}"/>'

    a = max(m.roughness, 0.02) ** 2  # α = roughness²; 0.02 keeps the GGX lobe finite
    if m.kind == "metal":
        inner = (f'<bsdf type="roughconductor"><string name="distribution" value="ggx"/><float name="alpha" '
                 f'value="{a:.5f}"/><string name="material" value="none"/>{colour("specular_reflectance")}</bsdf>')
    elif m.kind == "plastic":
        inner = (f'<bsdf type="roughplastic"><string name="distribution" value="ggx"/><float name="alpha" '
                 f'value="{a:.5f}"/>{colour("diffuse_reflectance")}</bsdf>')
    else:
        inner = f'<bsdf type="diffuse">{colour("reflectance")}</bsdf>'
    return f'<bsdf type="twosided">{inner}</bsdf>'


def _write_ply(path: Path, o: Obj) -> None:
    from plyfile import PlyData, PlyElement

    v = np.empty(len(o.pos), dtype=[("x", "f4"), ("y", "f4"), ("z", "f4"), ("u", "f4"), ("v", "f4")])
    v["x"], v["y"], v["z"] = o.pos.T
    v["u"], v["v"] = o.uv.T
    f = np.empty(len(o.tri), dtype=[("vertex_indices", "i4", (3,))])
    f["vertex_indices"] = o.tri
    PlyData([PlyElement.describe(v, "vertex"), PlyElement.describe(f, "face")]).write(str(path))


def _rect_matrix(center, u_half, v_half) -> str:
    """to_world of a Mitsuba `rectangle` ([−1, 1]², normal +z) spanning ±u_half, ±v_half about `center`;
    its normal is u × v."""
    n = np.cross(u_half, v_half)
    n = n / np.linalg.norm(n)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = u_half, v_half, n, center
    return " ".join(f"{x:.6f}" for x in m.ravel())


def build_house(spec: HouseSpec):
    """The objects, lights and panes of `spec` (no files)."""
    rng = np.random.default_rng(spec.seed)
    xs = np.concatenate([[0.0], np.cumsum(spec.columns)])
    ys = np.concatenate([[0.0], np.cumsum(spec.rows)])
    nx, ny, H = len(spec.columns), len(spec.rows), spec.height
    objs: list[Obj] = []
    lights: list[Light] = []
    panes: list[Pane] = []

    def pick_material(base_colours, allow_texture=True, allow_glossy=False):
        c = base_colours[rng.integers(len(base_colours))]
        m = Material(color=tuple(float(x) for x in c))
        r = rng.random()
        if allow_glossy and r < spec.metal_fraction:
            m.kind, m.roughness = "metal", float(rng.uniform(0.2, 0.5))
            m.color = tuple(float(x) for x in rng.uniform(0.55, 0.95, 3))
        elif allow_glossy and r < spec.metal_fraction + spec.plastic_fraction:
            m.kind, m.roughness = "plastic", float(rng.uniform(0.15, 0.4))
        if allow_texture and m.kind != "metal" and rng.random() < spec.textured_fraction:
            m.texture = ["checker", "stripes", "noise"][rng.integers(3)]
            m.color2 = tuple(float(x) for x in np.asarray(m.color) * rng.uniform(0.25, 0.6))
            m.tile = float(rng.uniform(0.3, 0.8))
        return m

    # Doors: a spanning tree over the grid (random order of a randomised depth-first walk) plus extras.
    doors = set()
    seen, stack = {(0, 0)}, [(0, 0)]
    while stack:
        i, j = stack[-1]
        nbrs = [(i + di, j + dj) for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1))
                if 0 <= i + di < nx and 0 <= j + dj < ny and (i + di, j + dj) not in seen]
        if not nbrs:
            stack.pop()
            continue
        n = nbrs[rng.integers(len(nbrs))]
        doors.add(tuple(sorted([(i, j), n])))
        seen.add(n)
        stack.append(n)
    for i in range(nx):
        for j in range(ny):
            for n in ((i + 1, j), (i, j + 1)):
                if n[0] < nx and n[1] < ny and rng.random() < spec.extra_doors:
                    doors.add(((i, j), n))

    # Walls along grid lines: vertical lines x = xs[i] (segments per row j), horizontal y = ys[j].
    wall_mat = {}
    for j in range(ny):
        for i in range(nx + 1):
            a, b = np.array([xs[i], ys[j], 0]), np.array([xs[i], ys[j + 1], 0])
            exterior = i in (0, nx)
            inward = np.array([1.0 if i == 0 else -1.0, 0, 0])
            key = ("x", i, j)
            wall_mat[key] = (a, b, inward, exterior, ((i - 1, j), (i, j)))
    for i in range(nx):
        for j in range(ny + 1):
            a, b = np.array([xs[i], ys[j], 0]), np.array([xs[i + 1], ys[j], 0])
            exterior = j in (0, ny)
            inward = np.array([0, 1.0 if j == 0 else -1.0, 0])
            wall_mat[("y", i, j)] = (a, b, inward, exterior, ((i, j - 1), (i, j)))
    for key, (a, b, inward, exterior, pair) in wall_mat.items():
        length = float(np.linalg.norm(b - a))
        holes = []
        if not exterior and tuple(sorted(pair)) in doors:
            dw, dh = spec.door_size
            s0 = float(rng.uniform(0.2, max(0.2, length - dw - 0.2)))
            holes.append((s0, s0 + dw, 0.0, dh))
        if exterior and spec.windows_per_exterior_wall > 0:
            k = rng.poisson(spec.windows_per_exterior_wall)
            ww, wh = spec.window_size
            slots = int((length - 0.3) // (ww + 0.3))
            for slot in sorted(rng.choice(max(slots, 0), size=min(k, max(slots, 0)), replace=False)):
                s0 = 0.3 + slot * (ww + 0.3) + float(rng.uniform(0, 0.05))
                holes.append((s0, s0 + ww, spec.window_sill, spec.window_sill + wh))
                along = (b - a) / length
                c = a + (s0 + ww / 2) * along + np.array([0, 0, spec.window_sill + wh / 2])
                panes.append(Pane(f"window-{len(panes)}", c, along, (ww, wh), inward))
        if not exterior:
            inward = np.cross([0, 0, 1.0], (b - a) / length)  # either side: the wall is two-sided
        m = pick_material(WALL_COLOURS)
        o = Obj(f"wall-{key[0]}{key[1]}-{key[2]}", m)
        o.add(*wall_with_holes(a, b, H, holes, inward, m.tile))
        objs.append(o)

    uplight_colours = list(spec.uplights)
    for i in range(nx):
        for j in range(ny):
            r = i * ny + j
            lo = np.array([xs[i], ys[j], 0.0])
            hi = np.array([xs[i + 1], ys[j + 1], H])
            size = hi - lo
            n = spec.surface_tessellation
            fm = Material(color=(0.55, 0.42, 0.30))
            if spec.floor_texture:
                fm.texture, fm.color, fm.color2, fm.tile = spec.floor_texture, (0.45, 0.30, 0.18), (0.70, 0.52, 0.33), 1.0
            f = Obj(f"floor-{r}", fm)
            f.add(*grid_quad(lo, [size[0], 0, 0], [0, size[1], 0], n, n, fm.tile))
            c = Obj(f"ceiling-{r}", Material(color=(0.82, 0.82, 0.80)))
            c.add(*grid_quad(lo + [0, 0, H], [0, size[1], 0], [size[0], 0, 0], n, n))
            objs += [f, c]
            colour = spec.ceiling_lights[r % len(spec.ceiling_lights)] if spec.ceiling_lights else ""
            if colour:
                lx, ly = spec.light_size
                lights.append(Light(f"light-ceiling-{r}", (lo + hi) / 2 * [1, 1, 0] + [0, 0, H - 0.01],
                                    (lx, ly), False, LIGHT_COLOURS[colour]))
            # Furniture: rejection-sampled footprints that keep FREE_RADIUS of floor free around the room centre
            # (the tripod needs a place) and do not overlap.
            placed = []

            def place(w, d, margin=0.05):
                for _ in range(200):
                    p = rng.uniform(lo[:2] + margin, hi[:2] - margin - [w, d])
                    q = p + [w, d]
                    centre = (lo[:2] + hi[:2]) / 2
                    if np.linalg.norm(np.clip(centre, p, q) - centre) < FREE_RADIUS:
                        continue
                    if any(np.all(p < b2 + 0.1) and np.all(a2 < q + 0.1) for a2, b2 in placed):
                        continue
                    placed.append((p, q))
                    return p, q
                return None

            for k in range(spec.cabinets_per_room):
                fp = place(*rng.uniform([0.4, 0.4], [0.9, 0.6]))
                if fp is None:
                    continue
                top = min(1.95, H - 0.2)
                m = pick_material(FURNITURE_COLOURS)
                o = Obj(f"cabinet-{r}-{k}", m)
                o.add(*box([*fp[0], 0.0], [*fp[1], top], spec.box_tessellation, m.tile, tray=TRAY_RIM))
                objs.append(o)
                if uplight_colours and k == 0:
                    colour = uplight_colours.pop(0)
                    inset = 0.05  # metres inside the tray's rim
                    ctr = np.array([*(fp[0] + fp[1]) / 2, top + UPLIGHT_GAP])
                    lights.append(Light(f"uplight-{r}", ctr, tuple(fp[1] - fp[0] - 2 * inset), True,
                                        LIGHT_COLOURS[colour]))
            for k in range(int(rng.integers(spec.furniture_per_room[0], spec.furniture_per_room[1] + 1))):
                w, d, h = rng.uniform([0.4, 0.4, 0.4], [1.0, 0.9, 1.1])
                fp = place(w, d)
                if fp is None:
                    continue
                m = pick_material(FURNITURE_COLOURS, allow_glossy=True)
                o = Obj(f"box-{r}-{k}", m)
                o.add(*box([*fp[0], 0.001], [*fp[1], h], spec.box_tessellation, m.tile))
                objs.append(o)
            for k in range(spec.spheres_per_room):
                rad = float(rng.uniform(0.12, 0.25))
                fp = place(2 * rad, 2 * rad)
                if fp is None:
                    continue
                m = pick_material(FURNITURE_COLOURS, allow_glossy=True)
                o = Obj(f"sphere-{r}-{k}", m)
                o.add(*icosphere([*(fp[0] + fp[1]) / 2, rad + 0.001], rad, spec.sphere_subdivisions))
                objs.append(o)
    return objs, lights, panes


def write_scene(spec: HouseSpec, out_dir: Path) -> Path:
    """Writes `scene.xml`, `meshes/` and `textures/` of `spec` into `out_dir`; returns the XML path."""
    out_dir = Path(out_dir)
    (out_dir / "meshes").mkdir(parents=True, exist_ok=True)
    (out_dir / "textures").mkdir(parents=True, exist_ok=True)
    objs, lights, panes = build_house(spec)
    trng = np.random.default_rng(spec.seed + 1)
    parts = ['<scene version="3.0.0">']
    for o in objs:
        tex = None
        if o.material.texture:
            tex = o.name
            write_png(out_dir / "textures" / f"{tex}.png",
                      texture_image(o.material.texture, o.material.color, o.material.color2, trng))
        _write_ply(out_dir / "meshes" / f"{o.name}.ply", o)
        parts.append(f'<shape type="ply" id="{o.name}"><string name="filename" value="meshes/{o.name}.ply"/>'
                     f'<boolean name="face_normals" value="true"/>{_material_xml(o.material, tex)}</shape>')
    for li in lights:
        lx, ly = li.size
        u, v = np.array([lx / 2, 0, 0]), np.array([0, ly / 2, 0])
        if not li.normal_up:
            v = -v  # u × v points down: the panel emits into the room below it
        r = li.radiance
        parts.append(
            f'<shape type="rectangle" id="{li.name}"><transform name="to_world"><matrix value="'
            f'{_rect_matrix(li.center, u, v)}"/></transform><bsdf type="twosided"><bsdf type="diffuse">'
            f'<rgb name="reflectance" value="0.8, 0.8, 0.8"/></bsdf></bsdf><emitter type="area">'
            f'<rgb name="radiance" value="{r[0]}, {r[1]}, {r[2]}"/></emitter></shape>')
    for p in panes:
        w, h = p.size
        u = p.along * w / 2
        v = np.array([0, 0, h / 2])
        if np.dot(np.cross(u, v), p.inward) < 0:
            u = -u
        parts.append(f'<shape type="rectangle" id="{p.name}-pane"><transform name="to_world"><matrix value="'
                     f'{_rect_matrix(p.center, u, v)}"/></transform><bsdf type="null"/></shape>')
    if spec.sky == "envmap":
        from .layout import write_exr

        write_exr(out_dir / "textures" / "sky.exr", sky_image(spec.sky_radiance))
        # Mitsuba's envmap is +y up; rotating +90° about x turns it to +z up.
        parts.append('<emitter type="envmap"><string name="filename" value="textures/sky.exr"/>'
                     '<transform name="to_world"><rotate x="1" angle="90"/></transform></emitter>')
    elif spec.sky == "constant":
        r = spec.sky_radiance
        parts.append(f'<emitter type="constant"><rgb name="radiance" value="{r[0]}, {r[1]}, {r[2]}"/></emitter>')
    parts.append("</scene>")
    path = out_dir / "scene.xml"
    path.write_text("\n".join(parts) + "\n")
    return path


def triangle_count(spec: HouseSpec) -> tuple[int, int, int]:
    """(objects, triangles, lights) of a spec without writing files."""
    objs, lights, panes = build_house(spec)
    return len(objs) + len(lights) + len(panes), sum(len(o.tri) for o in objs) + 2 * (len(lights) + len(panes)), len(lights)
