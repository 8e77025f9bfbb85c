"""examples/dask_bake.py on a local Dask cluster of 2 workers (workers in this process, and
processes): 8 meshes baked into the same tiles as a serial loop in this process. Times are
printed for the record, not asserted (speed is measured, not tested: the example's
--compare-serial)."""

import importlib.util
import math
import pathlib
import time

import numpy as np
import pytest

import distile

pytest.importorskip("dask.distributed")


def write_torus(path, minor_radius, segments=48, rings=16):
    """A closed torus (major radius 1) lying in the xy plane, as an OBJ file."""
    lines = []
    for i in range(segments):
        u = 2 * math.pi * i / segments
        for j in range(rings):
            v = 2 * math.pi * j / rings
            radius = 1 + minor_radius * math.cos(v)
            lines.append(f"v {radius * math.cos(u):.9f} {radius * math.sin(u):.9f} "
                         f"{minor_radius * math.sin(v):.9f}")
    for i in range(segments):
        for j in range(rings):
            a = i * rings + j + 1
            b = (i + 1) % segments * rings + j + 1
            c = (i + 1) % segments * rings + (j + 1) % rings + 1
            d = i * rings + (j + 1) % rings + 1
            lines += [f"f {a} {b} {c}", f"f {a} {c} {d}"]
    path.write_text("\n".join(lines) + "\n")


def load_example(source_dir):
    spec = importlib.util.spec_from_file_location(
        "dask_bake", source_dir / "examples" / "dask_bake.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("processes", [False, True], ids=["threads", "processes"])
def test_dask_bakes_eight_meshes_as_a_serial_loop_does(tmp_path, source_dir, monkeypatch,
                                                       processes):
    from dask.distributed import Client

    example = load_example(source_dir)
    folder = tmp_path / "meshes"
    folder.mkdir()
    for index in range(8):
        write_torus(folder / f"torus{index}.obj", 0.12 + 0.02 * index)
    meshes = example.meshes_in(folder)
    assert len(meshes) == 8
    size = "64x64x16"

    # Each run bakes into its own empty cache, so neither reads the other's tiles. Workers in
    # this process set its DISTILE_CACHE and bake_one sets it too, which monkeypatch restores
    # afterwards.
    monkeypatch.setenv("DISTILE_CACHE", str(tmp_path / "cache-dask"))
    start = time.perf_counter()
    with example.local_cluster(2, processes) as cluster, Client(cluster) as client:
        baked = example.bake_folder(client, meshes, tmp_path / "dask", size,
                                    cache=str(tmp_path / "cache-dask"))
    dask_seconds = time.perf_counter() - start

    # The serial loop runs here, with all cores (threads 0).
    monkeypatch.setenv("DISTILE_CACHE", str(tmp_path / "cache-serial"))
    start = time.perf_counter()
    serial = {}
    for mesh in meshes:
        serial[mesh.stem] = example.bake_one(str(mesh), str(tmp_path / f"{mesh.stem}.serial.exr"),
                                             size, str(tmp_path / "cache-serial"), 0)
    serial_seconds = time.perf_counter() - start
    workers = "2 processes x 1 thread" if processes else "2 workers in this process"
    print(f"8 meshes {size}: Dask ({workers}, cluster start included) "
          f"{dask_seconds:.2f} s, serial loop (all cores) {serial_seconds:.2f} s")

    assert len(baked) == 8
    for mesh in meshes:
        tile = distile.load_tile(tmp_path / "dask" / f"{mesh.stem}.exr")
        reference = distile.load_tile(tmp_path / f"{mesh.stem}.serial.exr")
        assert tile.metadata["hash"] == serial[mesh.stem]
        assert baked[str(tmp_path / "dask" / f"{mesh.stem}.exr")] == serial[mesh.stem]
        np.testing.assert_array_equal(tile.array, reference.array)
        assert tile.metadata["source"] == "mesh"
    # The tiles differ from one another: each is its own mesh's.
    assert len(set(serial.values())) == 8


def test_dask_example_refuses_a_bad_mesh_with_distiles_message(tmp_path, source_dir, monkeypatch,
                                                               capsys):
    example = load_example(source_dir)
    folder = tmp_path / "meshes"
    folder.mkdir()
    write_torus(folder / "good.obj", 0.2)
    (folder / "broken.obj").write_text("v 0 0 0\nf 1 2 3\n")
    monkeypatch.setenv("DISTILE_CACHE", str(tmp_path / "cache"))
    with pytest.raises(SystemExit) as exit_status:
        example.main([str(folder), str(tmp_path / "tiles"), "--size", "32x32x8"])
    assert exit_status.value.code == 2
    message = capsys.readouterr().err
    assert "broken.obj: line 2" in message and "refers to vertex 2" in message
    assert not (tmp_path / "tiles" / "broken.exr").exists()

    with pytest.raises(SystemExit) as exit_status:
        example.main([str(tmp_path / "no-such-folder"), str(tmp_path / "tiles")])
    assert exit_status.value.code == 2
    assert "is not a folder" in capsys.readouterr().err
