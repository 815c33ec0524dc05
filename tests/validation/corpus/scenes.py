"""The named scenes of the corpus: a Mitsuba XML source (external or generated) and default build settings.

| name            | source                                  | what it tests                                          |
|-----------------|-----------------------------------------|--------------------------------------------------------|
| modern-hall     | Bitterli's staircase2 (../shared/data)  | 13 disk/rectangle lights, textures, plastic, metals    |
| room-textured   | generator: 3 × 2.5 × 2.2 m room         | textures on floor, walls and boxes; warm ceiling light, |
|                 |                                         | hidden white uplight                                   |
| room-two-lights | generator: same room                    | a cool ceiling light and a hidden orange uplight;      |
|                 |                                         | boxes drawn 35 % rough metal, 35 % rough plastic       |
| room-daylight   | generator: same room with windows       | no lamps: an envmap sky through window panes           |
| house           | generator: 12 rooms joined by doors     | scale: ≥ 500 k triangles, ≥ 150 objects, ≥ 8 lights    |
| tiny            | generator: the textured room, 1 box     | the test scene (40 × 32 pixels, one tripod position)   |
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from .generate import HouseSpec

ROOM = dict(columns=(3.0,), rows=(2.5,), height=2.2)


@dataclass
class SceneEntry:
    name: str
    spec: HouseSpec | None = None  # generated scenes
    xml: Path | None = None  # external scenes
    up: str = "z"
    defaults: dict = field(default_factory=dict)


def shared_data() -> Path:
    from support import SHARED_DATA

    return SHARED_DATA


ROOM_DEFAULTS = dict(width=160, height=128, spp=128, positions=3, novel_positions=2)
SCENES = {
    "modern-hall": SceneEntry("modern-hall", xml=Path("bitterli-staircase2/scene.xml"), up="y",
                              defaults=dict(width=160, height=128, spp=64, positions=4, novel_positions=2)),
    "room-textured": SceneEntry("room-textured", HouseSpec(
        name="room-textured", seed=11, **ROOM, furniture_per_room=(2, 2), textured_fraction=0.8,
        ceiling_lights=("warm",), uplights=("white",)), defaults=ROOM_DEFAULTS),
    "room-two-lights": SceneEntry("room-two-lights", HouseSpec(
        name="room-two-lights", seed=12, **ROOM, furniture_per_room=(2, 3), textured_fraction=0.3,
        metal_fraction=0.35, plastic_fraction=0.35, ceiling_lights=("cool",), uplights=("orange",)),
        defaults=ROOM_DEFAULTS),
    "room-daylight": SceneEntry("room-daylight", HouseSpec(
        name="room-daylight", seed=13, **ROOM, furniture_per_room=(1, 2), textured_fraction=0.5,
        ceiling_lights=(), cabinets_per_room=0, windows_per_exterior_wall=1.0, sky="envmap",
        sky_radiance=(3.0, 3.2, 3.6)), defaults=dict(ROOM_DEFAULTS, spp=256)),
    "house": SceneEntry("house", HouseSpec(
        name="house", seed=14, columns=(4.0, 3.5, 4.0), rows=(3.5, 3.0, 3.5, 3.0), height=2.5,
        furniture_per_room=(6, 9), cabinets_per_room=2, spheres_per_room=3, box_tessellation=17,
        sphere_subdivisions=4, surface_tessellation=8, textured_fraction=0.4, metal_fraction=0.15,
        plastic_fraction=0.25, ceiling_lights=("warm", "white", "cool", "warm", ""),
        uplights=("orange", "white", "green", "warm"), windows_per_exterior_wall=0.7, sky="envmap"),
        defaults=dict(width=80, height=64, spp=16, positions=12, novel_positions=3, placement="coverage")),
    "tiny": SceneEntry("tiny", HouseSpec(
        name="tiny", seed=5, **ROOM, furniture_per_room=(1, 1), textured_fraction=1.0,
        ceiling_lights=("warm",), uplights=("cool",)),
        defaults=dict(width=40, height=32, spp=8, positions=1, novel_positions=1)),
}


def resolve(name: str, work_dir: Path):
    """(XML path, up axis, defaults) of a named scene, writing generated ones under `work_dir/source`;
    a path to an XML file is taken as is (z-up unless the caller says otherwise)."""
    from .generate import write_scene

    if name not in SCENES:
        p = Path(name)
        if p.is_file():
            return p, "z", {}
        raise SystemExit(f"unknown scene {name!r}: expected one of {', '.join(SCENES)} or an XML file")
    e = SCENES[name]
    if e.spec is not None:
        return write_scene(e.spec, Path(work_dir) / "source"), e.up, e.defaults
    xml = shared_data() / e.xml
    if not xml.is_file():
        raise SystemExit(f"{xml} not found (the Bitterli scene lives in ../shared/data beside the repository)")
    return xml, e.up, e.defaults
