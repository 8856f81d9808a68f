"""Write seed corpora for the fuzz harnesses into ``<FOLDER>/<target>/``.

Usage: ``python fuzz/make_seeds.py [FOLDER]`` (default ``fuzz/corpus``; see
README.md). Seeds are small valid inputs of every format, so the fuzzer starts
from files that get deep into the parsers.
"""

from __future__ import annotations

import io
import sys
from pathlib import Path

import numpy as np
import trimesh

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import targets  # noqa: E402


def _model_seeds() -> dict[str, tuple[str, bytes]]:
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    tet = trimesh.Trimesh(vertices=[[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
                          faces=[[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], process=False)
    cloud = np.random.default_rng(0).normal(size=(6, 3)).round(3)
    seeds: dict[str, tuple[str, bytes]] = {}
    for name, mesh in (("box", box), ("tet", tet)):
        seeds[f"{name}_obj"] = (".obj", mesh.export(file_type="obj").encode())
        seeds[f"{name}_stl_ascii"] = (".stl", mesh.export(file_type="stl_ascii").encode())
        seeds[f"{name}_stl"] = (".stl", mesh.export(file_type="stl"))
        seeds[f"{name}_ply_ascii"] = (".ply", mesh.export(file_type="ply", encoding="ascii"))
        seeds[f"{name}_ply"] = (".ply", mesh.export(file_type="ply"))
        seeds[f"{name}_off"] = (".off", mesh.export(file_type="off").encode())
        seeds[f"{name}_glb"] = (".glb", mesh.export(file_type="glb"))
        seeds[f"{name}_gltf"] = (".gltf", trimesh.Scene(mesh).export(
            file_type="gltf", embed_buffers=True)["model.gltf"])
    seeds["cloud_ply_ascii"] = (".ply", trimesh.PointCloud(cloud).export(
        file_type="ply", encoding="ascii"))
    seeds["cloud_ply"] = (".ply", trimesh.PointCloud(cloud).export(file_type="ply"))
    buf = io.StringIO()
    np.savetxt(buf, cloud)
    seeds["cloud_xyz"] = (".xyz", buf.getvalue().encode())
    seeds["cloud_csv"] = (".csv", ("x,y,z\n" + "\n".join(
        ",".join(map(str, p)) for p in cloud.tolist()) + "\n").encode())
    return seeds


def _config_seeds() -> dict[str, bytes]:
    raw = {
        "small": 'stipples = 50\nmethod = "hyperbola"\nlight-elevation = 40.0\n',
        "tool": 'tool = "vbit"\ntool-angle = 60\ntip-flat = 0.01\ndepth = 0.05\n',
        "plate": "plate-width = 100\nplate_height = 80.5\nstock-thickness = 2\n",
        "view": "view-distance = 450.0\nview-range = 30\neye-height = 120\nipd = 60\n",
        "spacing": "spacing = 2.5\nseed = 7\nstrict = true\nband = 0.1\n",
    }
    seeds = {f"raw_{k}": b"\x00" + v.encode() for k, v in raw.items()}
    # generator mode: odd first byte, the rest picks keys and values
    for i in range(8):
        seeds[f"gen_{i}"] = bytes([1]) + bytes(np.random.default_rng(i).integers(0, 256, 24))
    return seeds


def _gcode_seeds() -> dict[str, bytes]:
    from specholo.fabrication.programs.gcode import GcodeOptions, write_gcode
    from specholo.setup import Machining, Tool
    from specholo.toolpaths.grooves import Grooves

    vertices = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [20.0, 5.0], [-5.0, -5.0],
                         [1.0, 1.0], [2.0, 1.5], [4.0, 1.5]])
    bulges = np.array([0.5, -0.3, 0.0, 0.0, 0.0, np.tan(np.radians(270) / 4), -1.0, 0.0])
    grooves = Grooves(vertices, bulges, np.array([0, 4, 5, 8]), np.array([4, 4, 9]))
    seeds = {}
    tmp = targets.scratch("seed.gcode")
    for dialect in ("grbl", "linuxcnc", "marlin"):
        for units in ("mm", "inch"):
            write_gcode(tmp, grooves, Tool(), Machining(300.0, 100.0, 1.0, 12000.0),
                        header={"design": "seed"},
                        options=GcodeOptions(dialect=dialect, units=units))
            seeds[f"{dialect}_{units}"] = tmp.read_bytes()
    seeds["hand"] = (b"%\nG21 G90 G17\n(stipple 3)\nG0 Z1\nG0 X1 Y1\nG1 Z-0.1 F100\n"
                     b"G2 X3 Y1 I1 J0 ; half circle\nG1 X3 Y2\nG0 Z1\nM2\n%\n")
    # raw mode: even first byte; generator mode: odd first byte
    seeds = {k: b"\x00" + v for k, v in seeds.items()}
    for i in range(8):
        seeds[f"gen_{i}"] = bytes([1]) + bytes(np.random.default_rng(i).integers(0, 256, 40))
    return seeds


def _folder_seeds() -> dict[str, bytes]:
    """Each file of a tiny design folder whole (raw mode), and edits of it."""
    base = targets.base_folder()
    seeds = {}
    for i, name in enumerate(targets.FOLDER_FILES):
        stem = name.split(".")[0]
        seeds[f"raw_{stem}"] = bytes([i, 0]) + (base / name).read_bytes()
        for k in range(3):  # array or settings changes (1), byte edits (2)
            rest = bytes(np.random.default_rng(10 * i + k).integers(0, 256, 24))
            seeds[f"edit_{stem}_{k}"] = bytes([i, 1 + k % 2]) + rest
    return seeds


def _composition_seeds() -> dict[str, bytes]:
    raw = {
        "small": targets.SMALL_COMPOSITION,
        "light": 'mode = "light"\n' + targets.SMALL_COMPOSITION + "turn = 0.5\n",
        "cylinder": targets.SMALL_COMPOSITION.replace(
            "[[scene]]", '[host]\nkind = "cylinder"\nradius = 40\n[[scene]]'),
        "heightfield": targets.SMALL_COMPOSITION.replace(
            "[[scene]]", '[host]\nkind = "heightfield"\nfile = "hf.npz"\n[[scene]]'),
        "mesh": targets.SMALL_COMPOSITION.replace(
            "[[scene]]", '[host]\nkind = "mesh"\nfile = "tet.obj"\n[[scene]]'),
        "panels": targets.SMALL_COMPOSITION.replace(
            "[[scene]]", '[host]\nkind = "panels"\n[[host.panels]]\ncentre = [0, 0, 0]\n'
            'normal = [0, 0, 1]\nwidth = 80\nheight = 80\n[[scene]]'),
        "frames": targets.SMALL_COMPOSITION.replace('model = "tet.obj"',
                                                    'frames = "tet*.obj"'),
    }
    seeds = {f"raw_{k}": b"\x00" + v.encode() for k, v in raw.items()}
    for i in range(8):
        seeds[f"gen_{i}"] = bytes([1]) + bytes(np.random.default_rng(i).integers(0, 256, 24))
    return seeds


TARGETS = ("load_model", "config", "gcode", "folder", "composition")


def main() -> None:
    corpus = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "corpus"
    for sub in TARGETS:
        (corpus / sub).mkdir(parents=True, exist_ok=True)
    for name, (ext, body) in _model_seeds().items():
        (corpus / "load_model" / name).write_bytes(bytes([targets.MODEL_EXTS.index(ext)]) + body)
    for name, body in _config_seeds().items():
        (corpus / "config" / name).write_bytes(body)
    for name, body in _gcode_seeds().items():
        (corpus / "gcode" / name).write_bytes(body)
    for name, body in _folder_seeds().items():
        (corpus / "folder" / name).write_bytes(body)
    for name, body in _composition_seeds().items():
        (corpus / "composition" / name).write_bytes(body)
    for sub in TARGETS:
        print(f"{sub}: {len(list((corpus / sub).iterdir()))} seeds in {corpus / sub}")


if __name__ == "__main__":
    main()
