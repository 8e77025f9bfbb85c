#!/usr/bin/env python3
"""Bake a folder of detail meshes into distance tiles with Dask (dask.distributed).

Each mesh (OBJ, PLY, OFF, STL) becomes one tile, OUT/<mesh name>.exr, baked as
`distile bake mesh MESH --size SIZE` bakes it. The bakes are Dask tasks, largest mesh file
first: on a local cluster of --workers workers in this process by default (the bakes release
the GIL and share the cores), or on any running Dask cluster when --scheduler gives its
address, so the same script spreads a folder over many machines. Every worker bakes through
distile's bake cache: with --cache on a folder all workers share (a network file system), a
mesh baked once by any worker is never baked again. --compare-serial bakes the folder again
in a serial loop in this process and prints both times (each bakes into an empty cache).

    PYTHONPATH=build/python /usr/bin/python3 examples/dask_bake.py data/meshes tiles
    PYTHONPATH=build/python /usr/bin/python3 examples/dask_bake.py meshes tiles \\
        --scheduler tcp://scheduler:8786 --cache /mnt/cluster/distile-cache
"""

import argparse
import os
import pathlib
import shutil
import sys
import tempfile
import time

MESH_EXTENSIONS = {".obj", ".ply", ".off", ".stl"}


def bake_one(mesh, tile, size, cache=None, threads=None):
    """Bake `mesh` into the tile file `tile`; returns the tile's hash. `cache` and `threads`,
    when given, are set for the whole process first (a serial loop); the Dask tasks leave them
    None, as each worker set them once (WorkerSetup)."""
    import distile

    if cache:
        os.environ["DISTILE_CACHE"] = cache  # read by each bake
    if threads is not None:
        distile.set_threads(threads)
    baked = distile.bake_mesh(mesh, size=size)
    baked.save(tile)
    return baked.metadata["hash"]


class WorkerSetup:
    """A Dask worker plugin, run once on each worker (and on each that joins later) before
    its tasks: imports distile, so that no task pays for loading it, points the bake cache at
    `cache` and limits each bake to `threads` threads (0: all cores). By default (None) a
    worker in another process bakes with its share of the machine's cores (cores / the
    worker's threads); a worker in the client's process leaves the process's limit as it is,
    and its bakes share the cores through the process's one thread pool."""

    name = "distile-setup"

    def __init__(self, cache=None, threads=None):
        self.cache = cache
        self.threads = threads
        self.client_process = os.getpid()

    def setup(self, worker):
        import distile

        if self.cache:
            os.environ["DISTILE_CACHE"] = self.cache  # read by each bake
        threads = self.threads
        if threads is None and os.getpid() != self.client_process:
            threads = max(1, (os.cpu_count() or 1) // max(1, worker.state.nthreads))
        if threads is not None:
            distile.set_threads(threads)


def meshes_in(folder):
    """The mesh files of `folder`, sorted by name."""
    return sorted(path for path in pathlib.Path(folder).iterdir()
                  if path.suffix.lower() in MESH_EXTENSIONS)


def bake_folder(client, meshes, out, size="256x256x16", cache=None, threads=None):
    """Bakes each of `meshes` into `out`/<name>.exr on the Dask `client`'s workers, set up by
    WorkerSetup(`cache`, `threads`) (workers in this process set this process's bake cache and
    threads); returns {tile path: tile hash}, in the order of `meshes`. The largest mesh files
    are baked first, so that no long bake starts last while the other workers idle; only the
    hashes come back to the client, the workers write the tiles."""
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    client.register_worker_plugin(WorkerSetup(cache, threads), name=WorkerSetup.name)
    tiles = [str(out / (mesh.stem + ".exr")) for mesh in meshes]
    futures = [client.submit(bake_one, str(mesh), tile, size, pure=False,
                             priority=os.path.getsize(mesh))
               for mesh, tile in zip(meshes, tiles)]
    return dict(zip(tiles, client.gather(futures)))


def local_cluster(workers, processes=False):
    """A cluster on this machine: `workers` workers of one thread each in this process (the
    bakes release the GIL and share the cores through one thread pool), or with `processes`,
    `workers` processes of one thread each that import the same distile as this process (the
    build tree's, when it came from there)."""
    import distile
    from dask.distributed import LocalCluster

    if not processes:
        return LocalCluster(n_workers=workers, threads_per_worker=1, processes=False,
                            dashboard_address=None)
    package_parent = str(pathlib.Path(distile.__file__).resolve().parent.parent)
    paths = os.environ.get("PYTHONPATH", "").split(os.pathsep)
    if package_parent not in paths:
        os.environ["PYTHONPATH"] = os.pathsep.join([package_parent] + [p for p in paths if p])
    return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                        dashboard_address=None)


def refuse(message):
    """Exits with distile's status for refused input, 2, and `message` on stderr."""
    print(f"dask_bake: {message}", file=sys.stderr)
    sys.exit(2)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("meshes", help="folder of detail meshes (OBJ, PLY, OFF, STL)")
    parser.add_argument("out", help="folder to write the tiles to (created)")
    parser.add_argument("--size", default="256x256x16", help="tile size WxHxD in texels")
    parser.add_argument("--scheduler", help="address of a running Dask scheduler "
                        "(default: a local cluster)")
    parser.add_argument("--workers", type=int, default=2,
                        help="bakes at a time on the local cluster (default 2)")
    parser.add_argument("--processes", action="store_true",
                        help="make the local cluster's workers processes of one thread each")
    parser.add_argument("--threads", type=int,
                        help="threads of each bake (0: all cores; default: all cores on a local "
                        "cluster in this process, else each worker's share, cores / its "
                        "threads)")
    parser.add_argument("--cache", help="bake cache folder for every worker (default: each "
                        "worker's DISTILE_CACHE or its home folder's cache)")
    parser.add_argument("--compare-serial", action="store_true",
                        help="then bake the meshes again in a serial loop in this process "
                        "(into an empty cache of its own) and print both times; the Dask bakes "
                        "use an empty cache too, unless --cache gives one")
    arguments = parser.parse_args(argv)

    import distile  # loaded before the clock starts, as the serial loop has it
    from dask.distributed import Client

    if not os.path.isdir(arguments.meshes):
        refuse(f"{arguments.meshes} is not a folder; give the folder of the meshes to bake")
    meshes = meshes_in(os.path.abspath(arguments.meshes))
    if not meshes:
        refuse(f"no mesh files (OBJ, PLY, OFF, STL) in {arguments.meshes}")
    out = os.path.abspath(arguments.out)
    cache = arguments.cache and os.path.abspath(arguments.cache)
    scratch_cache = None
    if arguments.compare_serial and not cache:  # no tile from an earlier bake: an empty cache
        os.makedirs(out, exist_ok=True)
        scratch_cache = cache = tempfile.mkdtemp(prefix=".cache-", dir=out)
    start = time.perf_counter()
    threads = arguments.threads
    if arguments.scheduler:
        client = Client(arguments.scheduler)
        cluster = None
    else:
        if arguments.processes and threads is None:  # each process its share of the cores
            threads = max(1, (os.cpu_count() or 1) // arguments.workers)
        cluster = local_cluster(arguments.workers, arguments.processes)
        client = Client(cluster)
    try:
        started = time.perf_counter()
        baked = bake_folder(client, meshes, out, arguments.size, cache, threads)
        done = time.perf_counter()
    except (distile.InputError, distile.FormatError) as error:
        refuse(str(error))  # distile's message names the mesh and what is wrong with it
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
        if scratch_cache:
            shutil.rmtree(scratch_cache, ignore_errors=True)
    for tile, digest in baked.items():
        print(f"{tile} (distile:hash {digest})")
    if arguments.compare_serial:
        with tempfile.TemporaryDirectory() as scratch:
            serial_start = time.perf_counter()
            for mesh in meshes:
                bake_one(str(mesh), os.path.join(scratch, mesh.stem + ".exr"), arguments.size,
                         os.path.join(scratch, "cache"), 0)
            serial = time.perf_counter() - serial_start
        print(f"{len(meshes)} meshes {arguments.size}: Dask {done - start:.2f} s "
              f"({done - started:.2f} s after the cluster's start), serial loop {serial:.2f} s")


if __name__ == "__main__":
    main()
