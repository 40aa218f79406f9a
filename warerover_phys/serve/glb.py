"""glTF 2.0 binary (``.glb``) export of a layout and of an episode, built with trimesh
(imported lazily: ``pip install 'warerover-phys[serve]'``).

The scene is Y-up with metres: map ``x`` -> glTF ``X``, map ``y`` (rows, downward) ->
glTF ``Z``, height -> ``Y``. Floor, obstacles, shelves (1x1 and 2x2), stations and parking
are boxes merged per kind (one mesh each, vertex colours); every AGV is its own node named
``agv_<id>``. An episode export adds one glTF animation, ``episode``, with a translation and
a rotation channel per AGV (one keyframe per recorded sample, linear), which Blender and
three.js play. trimesh writes the static scene; the animation is appended to the GLB's JSON
and binary chunks here (trimesh does not write animations).
"""

from __future__ import annotations

import json
import struct
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .session import LiveSession

__all__ = ["layout_scene", "export_layout_glb", "export_episode_glb", "add_animation"]

# Okabe-Ito colours (RGBA 0-255), as in the MP4 renderer.
COLOURS = {"floor": (235, 235, 235, 255), "obstacle": (64, 64, 64, 255),
           "shelf": (140, 200, 238, 255), "station": (90, 190, 160, 255),
           "parking": (245, 238, 150, 255), "agv": (0, 114, 178, 255)}
HEIGHTS_M = {"obstacle": 1.0, "shelf": 1.6, "station": 0.3, "parking": 0.02}
MAX_KEYFRAMES = 600


def _trimesh():
    try:
        import trimesh
    except ImportError:  # pragma: no cover - depends on the environment
        from ..errors import WareroverError

        raise WareroverError("glTF export needs trimesh: pip install 'warerover-phys[serve]'") \
            from None
    return trimesh


def _boxes(trimesh, centres: list, extents: list, colour) -> object | None:
    if not centres:
        return None
    meshes = []
    for c, e in zip(centres, extents, strict=True):
        m = trimesh.creation.box(extents=e)
        m.apply_translation(c)
        meshes.append(m)
    mesh = trimesh.util.concatenate(meshes)
    mesh.visual.vertex_colors = np.tile(np.array(colour, np.uint8), (len(mesh.vertices), 1))
    return mesh


def layout_scene(grid: np.ndarray, cell_m: float, shelves: list[tuple[int, int, int]]):
    """A trimesh Scene of the floor: ``grid`` cell codes, ``shelves`` ``(row, col, size)``."""
    trimesh = _trimesh()
    rows, cols = grid.shape
    scene = trimesh.Scene()
    floor = _boxes(trimesh, [(cols * cell_m / 2, -0.01, rows * cell_m / 2)],
                   [(cols * cell_m, 0.02, rows * cell_m)], COLOURS["floor"])
    scene.add_geometry(floor, geom_name="floor", node_name="floor")
    for kind, code in (("obstacle", 1), ("station", 3), ("parking", 4)):
        rr, cc = np.nonzero(grid == code)
        h = HEIGHTS_M[kind]
        mesh = _boxes(trimesh, [((c + 0.5) * cell_m, h / 2, (r + 0.5) * cell_m)
                                for r, c in zip(rr, cc, strict=True)],
                      [(cell_m * (0.98 if kind != "obstacle" else 1.0), h,
                        cell_m * (0.98 if kind != "obstacle" else 1.0))] * len(rr),
                      COLOURS[kind])
        if mesh is not None:
            scene.add_geometry(mesh, geom_name=kind, node_name=kind)
    h = HEIGHTS_M["shelf"]
    mesh = _boxes(trimesh, [((c + s / 2) * cell_m, h / 2, (r + s / 2) * cell_m)
                            for r, c, s in shelves],
                  [(s * cell_m * 0.9, h, s * cell_m * 0.9) for _, _, s in shelves],
                  COLOURS["shelf"])
    if mesh is not None:
        scene.add_geometry(mesh, geom_name="shelves", node_name="shelves")
    return scene


def _session_layout(session: LiveSession):
    with session.lock:
        lay = session.sim.world.layout
        return (np.asarray(lay.grid).copy(), float(lay.cell_m),
                [(s.anchor[0], s.anchor[1], s.size) for s in lay.shelves])


def export_layout_glb(session: LiveSession, path: Path) -> int:
    """Write the live scenario's layout as ``.glb``; returns the file size in bytes."""
    grid, cell_m, shelves = _session_layout(session)
    data = layout_scene(grid, cell_m, shelves).export(file_type="glb")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data)
    return len(data)


def export_episode_glb(session: LiveSession, path: Path) -> int:
    """Write the layout, the AGV bodies and their motion so far (an animation) as ``.glb``."""
    trimesh = _trimesh()
    grid, cell_m, shelves = _session_layout(session)
    rec = session.recording()
    scene = layout_scene(grid, cell_m, shelves)
    names = []
    for i in range(rec.num_agvs):
        length, width = (float(v) for v in rec.body_m[i])
        body = trimesh.creation.box(extents=(length, 0.4, width))
        body.apply_translation((0, 0.2, 0))
        body.visual.vertex_colors = np.tile(np.array(COLOURS["agv"], np.uint8),
                                            (len(body.vertices), 1))
        name = f"agv_{i}"
        scene.add_geometry(body, geom_name=name, node_name=name,
                           transform=_pose(rec.x[0, i], rec.y[0, i], rec.heading[0, i]))
        names.append(name)
    keep = np.unique(np.linspace(0, len(rec.t) - 1, min(len(rec.t), MAX_KEYFRAMES))
                     .round().astype(int))
    glb = scene.export(file_type="glb")
    glb = add_animation(glb, names, rec.t[keep] - rec.t[0], rec.x[keep], rec.y[keep],
                        rec.heading[keep])
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(glb)
    return len(glb)


def _pose(x: float, y: float, heading: float) -> np.ndarray:
    m = np.eye(4)
    c, s = np.cos(-heading), np.sin(-heading)     # map y is glTF +Z: yaw is negated
    m[:3, :3] = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
    m[:3, 3] = (x, 0.0, y)
    return m


def _read_glb(data: bytes) -> tuple[dict, bytes]:
    magic, version, _ = struct.unpack_from("<III", data, 0)
    if magic != 0x46546C67 or version != 2:
        raise ValueError("not a glTF 2.0 binary")
    off, doc, binary = 12, None, b""
    while off < len(data):
        length, kind = struct.unpack_from("<II", data, off)
        chunk = data[off + 8: off + 8 + length]
        if kind == 0x4E4F534A:
            doc = json.loads(chunk.rstrip(b" \0").decode("utf-8"))
        elif kind == 0x004E4942:
            binary = chunk
        off += 8 + length
    if doc is None:
        raise ValueError("GLB has no JSON chunk")
    return doc, binary


def _write_glb(doc: dict, binary: bytes) -> bytes:
    js = json.dumps(doc, separators=(",", ":")).encode("utf-8")
    js += b" " * ((-len(js)) % 4)
    binary += b"\0" * ((-len(binary)) % 4)
    total = 12 + 8 + len(js) + 8 + len(binary)
    return b"".join([struct.pack("<III", 0x46546C67, 2, total),
                     struct.pack("<II", len(js), 0x4E4F534A), js,
                     struct.pack("<II", len(binary), 0x004E4942), binary])


def add_animation(glb: bytes, node_names: list[str], t: np.ndarray, x: np.ndarray,
                  y: np.ndarray, heading: np.ndarray, name: str = "episode") -> bytes:
    """Append a linear translation + rotation animation of the named nodes to a GLB
    (arrays (T, N): metres / radians; node ``i`` follows column ``i``)."""
    doc, binary = _read_glb(glb)
    nodes = {n.get("name"): i for i, n in enumerate(doc.get("nodes", []))}
    buf = bytearray(binary)
    views = doc.setdefault("bufferViews", [])
    accessors = doc.setdefault("accessors", [])

    def add(arr: np.ndarray, kind: str, minmax: bool = False) -> int:
        arr = np.ascontiguousarray(arr, dtype="<f4")
        while len(buf) % 4:
            buf.append(0)
        views.append({"buffer": 0, "byteOffset": len(buf), "byteLength": arr.nbytes})
        buf.extend(arr.tobytes())
        acc = {"bufferView": len(views) - 1, "componentType": 5126, "count": int(len(arr)),
               "type": kind}
        if minmax:
            acc["min"] = [float(arr.min())]
            acc["max"] = [float(arr.max())]
        accessors.append(acc)
        return len(accessors) - 1

    times = add(np.asarray(t, float), "SCALAR", minmax=True)
    samplers, channels = [], []
    for i, nm in enumerate(node_names):
        if nm not in nodes:
            continue
        node = doc["nodes"][nodes[nm]]
        node.pop("matrix", None)
        trans = np.stack([x[:, i], np.zeros(len(t)), y[:, i]], axis=1)
        half = -heading[:, i] / 2          # yaw about +Y (negated: map y is +Z)
        rot = np.stack([np.zeros(len(t)), np.sin(half), np.zeros(len(t)), np.cos(half)], axis=1)
        node["translation"] = [float(v) for v in trans[0]]
        node["rotation"] = [float(v) for v in rot[0]]
        for path, arr, kind in (("translation", trans, "VEC3"), ("rotation", rot, "VEC4")):
            samplers.append({"input": times, "output": add(arr, kind),
                             "interpolation": "LINEAR"})
            channels.append({"sampler": len(samplers) - 1,
                             "target": {"node": nodes[nm], "path": path}})
    doc.setdefault("animations", []).append({"name": name, "samplers": samplers,
                                             "channels": channels})
    doc["buffers"] = [{"byteLength": len(buf)}]
    return _write_glb(doc, bytes(buf))
