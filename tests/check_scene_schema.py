#!/usr/bin/env python3
"""Checks docs/scene.schema.json against the scene reader of `distile render`.

- The schema is a valid JSON Schema (draft 2020-12).
- Every scene in data/scenes/ is valid under it.
- Each scene of a list of bad scenes (a typo in a field name, values out of range, unknown
  enumerations) is refused by the schema AND by `distile render`, which exits non-zero and names
  the offending field.

Usage: check_scene_schema.py --source REPOSITORY --distile PATH/TO/distile
"""
import argparse
import copy
import glob
import json
import os
import subprocess
import sys
import tempfile

import jsonschema

# A scene the reader loads without baking anything: a bare plane.
BASE = {
    "camera": {"eye": [0, -3, 2], "target": [0, 0, 0], "up": [0, 0, 1], "fov_deg": 40},
    "image": {"width": 8, "height": 8, "spp": 1},
    "lights": [{"type": "directional", "direction": [-0.4, -0.3, -1], "color": [1, 1, 1],
                "angle_deg": 2}],
    "objects": [{"mesh": "plane", "transform": {"scale": 2},
                 "material": {"uv_scale": [4, 4], "depth": 0.05, "floor": "solid",
                              "color": [0.8, 0.8, 0.85]}}],
}


def edited(edit):
    scene = copy.deepcopy(BASE)
    edit(scene)
    return scene


def material(scene):
    return scene["objects"][0]["material"]


# (what, the field the reader's message must name, the scene)
BAD_SCENES = [
    ("typo in a field name", "uv_sclae",
     edited(lambda s: material(s).update({"uv_sclae": material(s).pop("uv_scale")}))),
    ("unknown top-level field", "camra", edited(lambda s: s.update({"camra": s.pop("camera")}))),
    ("field of view too wide", "camera.fov_deg", edited(lambda s: s["camera"].update(fov_deg=180))),
    ("eye not three numbers", "camera.eye", edited(lambda s: s["camera"].update(eye=[0, 1]))),
    ("no samples per pixel", "image.spp", edited(lambda s: s["image"].update(spp=0))),
    ("fractional width", "image.width", edited(lambda s: s["image"].update(width=640.5))),
    ("unknown light type", "lights[0].type", edited(lambda s: s["lights"][0].update(type="point"))),
    ("light too wide", "lights[0].angle_deg",
     edited(lambda s: s["lights"][0].update(angle_deg=89.5))),
    ("negative colour", "lights[0].color[1]",
     edited(lambda s: s["lights"][0].update(color=[1, -1, 1]))),
    ("colour too bright", "objects[0].material.color[0]",
     edited(lambda s: material(s).update(color=[2e9, 1, 1]))),
    ("zero light direction", "lights[0].direction",
     edited(lambda s: s["lights"][0].update(direction=[0, 0, 0]))),
    ("no objects", "objects", edited(lambda s: s.update(objects=[]))),
    ("object without mesh", "objects[0]", edited(lambda s: s["objects"][0].pop("mesh"))),
    ("zero scale", "objects[0].transform.scale",
     edited(lambda s: s["objects"][0]["transform"].update(scale=0))),
    ("unknown floor", "objects[0].material.floor",
     edited(lambda s: material(s).update(floor="closed"))),
    ("zero depth", "objects[0].material.depth", edited(lambda s: material(s).update(depth=0))),
    ("negative uv scale", "objects[0].material.uv_scale",
     edited(lambda s: material(s).update(uv_scale=[4, -1]))),
    ("unknown recipe", "objects[0].material.tile.bake",
     edited(lambda s: material(s).update(tile={"bake": "rivets"}))),
    ("a field and its older name", "objects[0].material.tile.rows_per_tile",
     edited(lambda s: material(s).update(tile={"bake": "chainmail", "rows": 4,
                                               "rows_per_tile": 4}))),
    ("unknown weave", "objects[0].material.tile.weave",
     edited(lambda s: material(s).update(tile={"bake": "chainmail", "weave": "byzantine"}))),
    ("no bars", "objects[0].material.tile.bars",
     edited(lambda s: material(s).update(tile={"bake": "grating", "bars": 0}))),
    ("negative band", "objects[0].material.tile.band",
     edited(lambda s: material(s).update(tile={"bake": "grating", "band": -1}))),
    ("height map without file", "objects[0].material.tile",
     edited(lambda s: material(s).update(tile={"bake": "heightmap"}))),
    ("fit given as text", "objects[0].material.tile.fit",
     edited(lambda s: material(s).update(tile={"bake": "mesh", "file": "ring.obj",
                                               "fit": "yes"}))),
    ("odd number of rows", "objects[0].material.tile",
     edited(lambda s: material(s).update(tile={"bake": "chainmail", "rows_per_tile": 3}))),
    ("tilt too large", "objects[0].material.tile.tilt_deg",
     edited(lambda s: material(s).update(tile={"bake": "chainmail", "tilt_deg": 61}))),
    ("size not WxHxD", "objects[0].material.tile.size",
     edited(lambda s: material(s).update(tile={"bake": "chainmail", "size": "256x256"}))),
    ("tile extent too small", "objects[0].material.tile.size",
     edited(lambda s: material(s).update(tile={"bake": "chainmail", "size": [256, 256, 1]}))),
    ("chain-mail option on a mesh recipe", "objects[0].material.tile.rings_per_row",
     edited(lambda s: material(s).update(
         tile={"bake": "mesh", "file": "ring.obj", "rings_per_row": 8}))),
    ("mesh recipe without file", "objects[0].material.tile",
     edited(lambda s: material(s).update(tile={"bake": "mesh"}))),
    ("unsigned given as text", "objects[0].material.tile.unsigned",
     edited(lambda s: material(s).update(tile={"bake": "mesh", "file": "ring.obj",
                                               "unsigned": "yes"}))),
    ("vdb recipe without file", "objects[0].material.tile",
     edited(lambda s: material(s).update(tile={"bake": "vdb"}))),
    ("vdb window of five numbers", "objects[0].material.tile.window",
     edited(lambda s: material(s).update(tile={"bake": "vdb", "file": "level.vdb",
                                               "window": [0, 0, 0, 1, 1]}))),
    ("mesh option on a vdb recipe", "objects[0].material.tile.thickness",
     edited(lambda s: material(s).update(tile={"bake": "vdb", "file": "level.vdb",
                                               "thickness": 1}))),
    ("mesh thickness without unsigned", "objects[0].material.tile.thickness",
     edited(lambda s: material(s).update(tile={"bake": "mesh", "file": "ring.obj",
                                               "thickness": 2}))),
    ("mesh thickness with unsigned false", "objects[0].material.tile.thickness",
     edited(lambda s: material(s).update(tile={"bake": "mesh", "file": "ring.obj",
                                               "unsigned": False, "thickness": 0}))),
    ("small ring radius on the European weave", "objects[0].material.tile.small_ring_radius",
     edited(lambda s: material(s).update(tile={"bake": "chainmail", "small_ring_radius": 0.2}))),
    ("mesh fit false without scale or offset", "objects[0].material.tile.fit",
     edited(lambda s: material(s).update(tile={"bake": "mesh", "file": "ring.obj",
                                               "fit": False}))),
    ("vdb fit false without scale or offset", "objects[0].material.tile.fit",
     edited(lambda s: material(s).update(tile={"bake": "vdb", "file": "level.vdb",
                                               "fit": False}))),
    ("vdb window with fit", "objects[0].material.tile.window",
     edited(lambda s: material(s).update(tile={"bake": "vdb", "file": "level.vdb",
                                               "window": [0, 0, 0, 1, 1, 1], "fit": True}))),
]

# Scenes the schema must accept (the reader's checks that need a bake are not run here).
GOOD_TILES = [
    ("Japanese weave with an odd number of rows",
     {"bake": "chainmail", "weave": "japanese4in1", "rows": 3}),
    ("Japanese weave with one row", {"bake": "chainmail", "weave": "japanese4in1", "rows": 1}),
    ("Japanese weave with small rings", {"bake": "chainmail", "weave": "japanese4in1",
                                         "small_ring_radius": 0.2, "small_wire_radius": 0.03}),
    ("mesh fit false with a scale", {"bake": "mesh", "file": "ring.obj", "fit": False,
                                     "scale": 2}),
    ("vdb window", {"bake": "vdb", "file": "level.vdb", "window": [0, 0, 0, 1, 1, 1]}),
    ("unsigned mesh with a thickness", {"bake": "mesh", "file": "ring.obj", "unsigned": True,
                                        "thickness": 2}),
]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--source", required=True, help="the repository's root folder")
    parser.add_argument("--distile", required=True, help="the distile command")
    arguments = parser.parse_args()

    with open(os.path.join(arguments.source, "docs", "scene.schema.json")) as file:
        schema = json.load(file)
    jsonschema.Draft202012Validator.check_schema(schema)
    validator = jsonschema.Draft202012Validator(schema)
    failures = []

    scenes = sorted(glob.glob(os.path.join(arguments.source, "data", "scenes", "*.json")))
    if not scenes:
        failures.append("no scenes found in data/scenes/")
    for path in scenes:
        with open(path) as file:
            errors = list(validator.iter_errors(json.load(file)))
        for error in errors:
            failures.append(f"{os.path.relpath(path, arguments.source)}: schema refuses "
                            f"{error.json_path}: {error.message}")
        print(f"{'ok  ' if not errors else 'FAIL'} schema accepts {os.path.basename(path)}")
    for what, tile in GOOD_TILES:
        scene = edited(lambda s: material(s).update(tile=tile))
        errors = list(validator.iter_errors(scene))
        print(f"{'ok  ' if not errors else 'FAIL'} schema accepts {what}")
        for error in errors:
            failures.append(f"{what}: schema refuses {error.json_path}: {error.message}")
    if validator.is_valid(BASE):
        print("ok   schema accepts the base scene of the bad cases")
    else:
        failures.append("the schema refuses the base scene of the bad cases")

    with tempfile.TemporaryDirectory() as folder:
        # The base scene itself must load and render (a tiny image), or the bad cases prove nothing.
        base_path = os.path.join(folder, "base.json")
        with open(base_path, "w") as file:
            json.dump(BASE, file)
        run = subprocess.run([arguments.distile, "render", base_path, "-o",
                              os.path.join(folder, "base.png")], capture_output=True, text=True)
        if run.returncode != 0:
            failures.append(f"distile render refuses the base scene: {run.stderr.strip()}")

        for index, (what, field, scene) in enumerate(BAD_SCENES):
            errors = list(validator.iter_errors(scene))
            schema_refuses = bool(errors)
            if index == 0 and not any(field in error.message for error in errors):
                failures.append(f"{what}: the schema's message does not name '{field}'")
            path = os.path.join(folder, f"bad{index}.json")
            with open(path, "w") as file:
                json.dump(scene, file)
            run = subprocess.run([arguments.distile, "render", path, "-o",
                                  os.path.join(folder, f"bad{index}.png")],
                                 capture_output=True, text=True)
            message = run.stderr.strip()
            reader_refuses = run.returncode != 0 and field in message
            verdict = "ok  " if schema_refuses and reader_refuses else "FAIL"
            print(f"{verdict} {what}: schema {'refuses' if schema_refuses else 'ACCEPTS'}, "
                  f"distile render exits {run.returncode}: {message.splitlines()[-1] if message else ''}")
            if not schema_refuses:
                failures.append(f"{what}: the schema accepts it")
            if not reader_refuses:
                failures.append(f"{what}: distile render exits {run.returncode} without naming "
                                f"'{field}': {message}")
            if os.path.exists(os.path.join(folder, f"bad{index}.png")):
                failures.append(f"{what}: distile render wrote an image")

    for failure in failures:
        print("FAIL", failure, file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
