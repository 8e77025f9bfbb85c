#!/usr/bin/env python3
"""Bake a folder of detail meshes into distance tiles with Dask (dask.distributed).

Each mesh (OBJ, PLY, OFF, STL) becomes one tile, OUT/<mesh name>.exr, baked as
`distile bake mesh MESH --size SIZE` bakes it. The bakes are Dask tasks: on a local cluster of
--workers processes (one thread each, each bake on one core) by default, or on any running Dask
cluster when --scheduler gives its address, so the same script spreads a folder over many
machines. Every worker bakes through distile's bake cache: with --cache on a folder all workers
share (a network file system), a mesh baked once by any worker is never baked again.

    PYTHONPATH=build/python /usr/bin/python3 examples/dask_bake.py data/meshes tiles
    PYTHONPATH=build/python /usr/bin/python3 examples/dask_bake.py meshes tiles \\
        --scheduler tcp://scheduler:8786 --cache /mnt/cluster/distile-cache
"""

import argparse
import os
import pathlib
import sys

MESH_EXTENSIONS = {".obj", ".ply", ".off", ".stl"}


def bake_one(mesh, tile, size, cache, threads):
    """One Dask task: bake `mesh` into the tile file `tile`; returns the tile's hash."""
    import distile

    if cache:
        os.environ["DISTILE_CACHE"] = cache  # read by each bake
    distile.set_threads(threads)
    baked = distile.bake_mesh(mesh, size=size)
    baked.save(tile)
    return baked.metadata["hash"]


def meshes_in(folder):
    """The mesh files of `folder`, sorted by name."""
    return sorted(path for path in pathlib.Path(folder).iterdir()
                  if path.suffix.lower() in MESH_EXTENSIONS)


def bake_folder(client, meshes, out, size="256x256x16", cache=None, threads=1):
    """Bakes each of `meshes` into `out`/<name>.exr on the Dask `client`'s workers, each with
    `threads` threads; returns {tile path: tile hash}, in the order of `meshes`."""
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    tiles = [str(out / (mesh.stem + ".exr")) for mesh in meshes]
    futures = [client.submit(bake_one, str(mesh), tile, size, cache, threads, pure=False)
               for mesh, tile in zip(meshes, tiles)]
    return dict(zip(tiles, client.gather(futures)))


def local_cluster(workers):
    """A cluster of `workers` processes on this machine, one thread each, that import the
    same distile as this process (the build tree's, when it came from there)."""
    import distile
    from dask.distributed import LocalCluster

    package_parent = str(pathlib.Path(distile.__file__).resolve().parent.parent)
    paths = os.environ.get("PYTHONPATH", "").split(os.pathsep)
    if package_parent not in paths:
        os.environ["PYTHONPATH"] = os.pathsep.join([package_parent] + [p for p in paths if p])
    return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                        dashboard_address=None)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("meshes", help="folder of detail meshes (OBJ, PLY, OFF, STL)")
    parser.add_argument("out", help="folder to write the tiles to (created)")
    parser.add_argument("--size", default="256x256x16", help="tile size WxHxD in texels")
    parser.add_argument("--scheduler", help="address of a running Dask scheduler "
                        "(default: a local cluster)")
    parser.add_argument("--workers", type=int, default=2,
                        help="processes of the local cluster (default 2)")
    parser.add_argument("--threads", type=int, default=1,
                        help="threads of each bake (default 1: one bake per core)")
    parser.add_argument("--cache", help="bake cache folder for every worker (default: each "
                        "worker's DISTILE_CACHE or its home folder's cache)")
    arguments = parser.parse_args(argv)

    from dask.distributed import Client

    meshes = meshes_in(arguments.meshes)
    if not meshes:
        sys.exit(f"dask_bake: no mesh files (OBJ, PLY, OFF, STL) in {arguments.meshes}")
    if arguments.scheduler:
        client = Client(arguments.scheduler)
        cluster = None
    else:
        cluster = local_cluster(arguments.workers)
        client = Client(cluster)
    try:
        baked = bake_folder(client, meshes, os.path.abspath(arguments.out), arguments.size,
                            arguments.cache and os.path.abspath(arguments.cache),
                            arguments.threads)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    for tile, digest in baked.items():
        print(f"{tile} (distile:hash {digest})")


if __name__ == "__main__":
    main()
