"""distile from Python: bake detail into distance tiles, read and write tiles, check them
against their truth, render scenes and compare renders (docs/python.md).

Every function calls the library function the `distile` command calls, with the command's
options under their flags' names in snake_case (``--rings-per-row`` is ``rings_per_row``).
Bad input raises :class:`InputError` or :class:`FormatError` (both ValueError) with the
command's message. Bakes and renders release the GIL.

    >>> import distile
    >>> tile = distile.bake_chainmail(size="64x64x8")
    >>> tile.array.shape            # (D, H, W) float32, no copy
    (8, 64, 64)
"""

import json as _json
import numbers as _numbers
import operator as _operator
import os as _os
import warnings as _warnings

from ._distile import (  # noqa: F401  (the package's names)
    FormatError,
    InputError,
    InternalError,
    Render,
    Tile,
    load_tile,
)
from . import _distile

__all__ = [
    "FormatError", "InputError", "InternalError", "Render", "Tile", "bake", "bake_chainmail",
    "bake_grating", "bake_heightmap", "bake_mesh", "bake_vdb", "check", "compare", "load_tile",
    "render", "set_threads",
]


def _plain(value):
    """NumPy numbers and arrays as the Python numbers and lists they hold (for json)."""
    if hasattr(value, "tolist"):
        return value.tolist()
    raise TypeError(f"{value!r} ({type(value).__name__}) is not a number, string, bool or list")


def _json_text(value, what):
    """`value` as JSON text; NaN and infinities, and a dict or list that holds itself, are
    refused as InputError naming `what`, not passed on as text the JSON reader cannot read."""
    try:
        return _json.dumps(value, allow_nan=False, default=_plain)
    except ValueError:
        pass
    try:
        _json.dumps(value, allow_nan=True, default=_plain)
    except ValueError:
        raise InputError(f"{what}: is not accepted; it holds itself") from None
    raise InputError(f"{what}: {value!r} is not accepted; numbers must be finite") from None


def _numpy_scalar(value, kinds):
    """Whether `value` is a NumPy scalar or 0-d array of one of the dtype `kinds` ("b", "iu",
    "iuf")."""
    dtype = getattr(value, "dtype", None)
    return dtype is not None and getattr(value, "shape", None) == () and dtype.kind in kinds


def _keyword(function, name, value, kind):
    """`value` of keyword `name` of `function`, checked to be of `kind`: "int" (32-bit), "uint64",
    "float", "bool", "str" or "xyz" (three numbers); with a trailing "?", None too (the
    default). NumPy scalars and 0-d arrays count as the Python numbers they hold, but a bool is
    no number here. A wrong type raises TypeError naming the keyword, an int beyond the kind's
    range InputError."""
    if kind.endswith("?"):
        if value is None:
            return None
        kind = kind[:-1]
    got = f"not {value!r} ({type(value).__name__})"
    is_bool = isinstance(value, bool) or _numpy_scalar(value, "b")
    if kind == "bool":
        if is_bool:
            return bool(value)
        raise TypeError(f"{function}(): {name} must be True or False, {got}")
    if kind in ("int", "uint64"):
        try:
            number = None if is_bool else _operator.index(value)
        except TypeError:
            number = None
        if number is not None:
            low, high = (-(2**31), 2**31 - 1) if kind == "int" else (0, 2**64 - 1)
            if not low <= number <= high:
                raise InputError(f"{name}: {number} is not accepted; it must be in "
                                 f"[{low}, {high}] at the very least")
            return number
        raise TypeError(f"{function}(): {name} must be a whole number, {got}")
    if kind == "float":
        if not is_bool and (isinstance(value, _numbers.Real) or _numpy_scalar(value, "iuf")):
            return float(value)
        raise TypeError(f"{function}(): {name} must be a number, {got}")
    if kind == "names":  # one name or several
        names = [value] if isinstance(value, str) else value
        if isinstance(names, (list, tuple)) and all(isinstance(item, str) for item in names):
            return list(names)
        raise TypeError(f"{function}(): {name} must be a name or a list of names, {got}")
    if kind == "reference":  # True: the analytic reference; False or None: none
        if is_bool or value is None:
            return "analytic" if value else None
        if isinstance(value, str):
            return value
        raise TypeError(f"{function}(): {name} must be True, False, \"analytic\", \"world\" or "
                        f"\"world-levelset\", {got}")
    if kind == "str":
        if isinstance(value, str):
            return value
        raise TypeError(f"{function}(): {name} must be a string, {got}")
    components = value.tolist() if hasattr(value, "tolist") else value
    if isinstance(components, (tuple, list)) and len(components) == 3:
        return [_keyword(function, name, component, "float") for component in components]
    raise TypeError(f"{function}(): {name} must be three numbers (x, y, z), {got}")


def _checked_keywords(function, options, kinds):
    """`options` after _keyword's check of each, as a new dict; unknown keywords are a
    TypeError, as Python gives for a function's own."""
    checked = {}
    for name, value in options.items():
        if name not in kinds:
            raise TypeError(f"{function}() got an unexpected keyword argument '{name}'")
        checked[name] = _keyword(function, name, value, kinds[name])
    return checked


def set_threads(threads):
    """Limit distile's work to `threads` threads (1 to 1024; 0: all cores), as the command's
    --threads; results do not depend on it."""
    _distile.set_threads(_keyword("set_threads", "threads", threads, "int"))


def _file_name(detail, keyword, file):
    """The file name `file` (str, bytes or os.PathLike) of keyword `keyword` of a bake, absolute;
    one the recipe's JSON cannot carry is InputError."""
    path = _os.fsdecode(_os.fspath(file))
    if "\0" in path:
        raise InputError(f"bake {detail}: {keyword}: {path!r} is not accepted; a file name cannot "
                         "hold a NUL character")
    path = _os.path.abspath(path)
    try:
        path.encode("utf-8")
    except UnicodeEncodeError:
        raise InputError(f"bake {detail}: {keyword}: {path!r} is not accepted; bake() takes file "
                         "names in UTF-8 (the distile command takes any)") from None
    return path


def _repeat(detail, repeat):
    """The (N, M) of a bake's `repeat`: two whole numbers, or "NxM" as `distile bake --repeat`
    takes it; the level set checks their range."""
    if isinstance(repeat, str):
        parts = repeat.lower().split("x")
        if len(parts) == 2 and all(part.strip().isdigit() for part in parts):
            return int(parts[0]), int(parts[1])
        raise InputError(f"bake {detail}: repeat: {repeat!r} is not accepted; give \"NxM\" or "
                         "(N, M), e.g. (2, 2)")
    components = repeat.tolist() if hasattr(repeat, "tolist") else repeat
    if isinstance(components, (tuple, list)) and len(components) == 2:
        return tuple(_keyword(f"bake_{detail}", "repeat", count, "int") for count in components)
    raise TypeError(f"bake_{detail}(): repeat must be two whole numbers (N, M) or \"NxM\", "
                    f"not {repeat!r} ({type(repeat).__name__})")


def _progress(function, progress):
    """`progress`: None or a callable of the fraction done; anything else is a TypeError."""
    if progress is None or callable(progress):
        return progress
    raise TypeError(f"{function}(): progress must be a callable of the fraction done (or None), "
                    f"not {progress!r} ({type(progress).__name__})")


def _bake(detail, file, options):
    """bake()'s work; its warnings are told at the line that called bake() or bake_*()."""
    recipe = {"bake": detail}
    if file is not None:
        recipe["file"] = _file_name(detail, "file", file)
    options = dict(options)
    vdb = options.pop("vdb", None)
    repeat = options.pop("repeat", None)
    progress = _progress(f"bake_{detail}", options.pop("progress", None))
    for name, value in options.items():
        recipe[name] = list(value) if isinstance(value, tuple) else value
        _json_text(recipe[name], name)  # a NaN refused under its keyword
    name = "bake " + str(detail)
    if vdb is None:
        if repeat is not None:
            raise InputError(f"{name}: repeat: needs vdb=FILE (it tiles the level set written "
                             "there)")
        tile, found = _distile.bake_recipe(_json_text(recipe, "bake"), name, progress)
    else:
        repeat_x, repeat_y = (1, 1) if repeat is None else _repeat(detail, repeat)
        tile, found = _distile.bake_recipe_with_level_set(
            _json_text(recipe, "bake"), name, _file_name(detail, "vdb", vdb), repeat_x, repeat_y,
            progress)
    for warning in found:
        _warnings.warn(warning, stacklevel=3)
    if progress is not None:
        progress(1.0)
    return tile


def bake(detail, file=None, **options):
    """Bake `detail` ("chainmail", "grating", "mesh", "heightmap" or "vdb"; the last three
    read `file`) into a Tile, as ``distile bake DETAIL [FILE]`` does, with its options as
    keywords: size="WxHxD" (or (W, H, D)), band, exact_texels, and the detail's own (a scene's
    bake recipe takes the same; docs/scene.md). The tile is kept in the bake cache
    (DISTILE_CACHE), so baking the same recipe again reads it back. What is odd about a mesh
    is told as a UserWarning. vdb=FILE also writes the level set the tile was sampled from (as
    --vdb; such a bake always runs: the cache keeps tiles only), repeat=(N, M) tiles it (as
    --repeat). progress: a callable given the fraction done (Ctrl-C ends a bake at a report)."""
    return _bake(detail, file, options)


def bake_chainmail(**options):
    """Chain mail (``distile bake chainmail``): weave, rings_per_row, rows, ring_radius,
    wire_radius, tilt, small_ring_radius, small_wire_radius, and size, band, exact_texels, vdb,
    repeat, progress (bake())."""
    return _bake("chainmail", None, options)


def bake_grating(**options):
    """A grating (``distile bake grating``): bars, bar_width, bar_height, edge_radius,
    layer_gap, and size, band, exact_texels, vdb, repeat, progress (bake())."""
    return _bake("grating", None, options)


def bake_mesh(file, **options):
    """A detail mesh, OBJ, PLY, OFF or STL (``distile bake mesh FILE``): fit, scale,
    offset=(x, y, z), unsigned, thickness, and size, band, exact_texels, vdb, repeat, progress
    (bake())."""
    return _bake("mesh", file, options)


def bake_heightmap(file, **options):
    """A grey image as heights (``distile bake heightmap IMAGE``): height_texels, and size,
    band, exact_texels, vdb, repeat, progress (bake())."""
    return _bake("heightmap", file, options)


def bake_vdb(file, **options):
    """A level set or fog volume from a .vdb file (``distile bake vdb FILE``): grid, iso, fit,
    scale, offset, window=(x0, y0, z0, x1, y1, z1), and size, band, exact_texels, vdb, repeat,
    progress (bake())."""
    return _bake("vdb", file, options)


_CHECK_KEYWORDS = {
    "samples": "int", "seed": "uint64", "max_overestimate": "float",
    "max_overestimate_share": "float", "max_rms": "float", "max_tracer_overestimate": "float",
    "max_near_error": "float?",
    "allow_sign_errors": "bool", "scale": "float?", "offset": "xyz?",
}

_RENDER_KEYWORDS = {
    "width": "int?", "height": "int?", "spp": "int?", "aovs": "bool", "reference": "reference",
    "reference_voxels": "float?", "no_skip": "names",
    "iterations": "int?", "epsilon": "float?", "march": "str?", "relaxation": "float?",
    "filter": "str?", "normal_filter": "str?", "shell": "str?", "shadows": "str?",
}


def check(tile, against=None, plot=None, **options):
    """How far `tile` (a Tile or a tile file) is from its truth, as ``distile check --json``:
    the report as a dict (``passed``, ``failures``, ``rms``, ``max_abs``, ...). `against`:
    None (the tile's own truth), "analytic", a mesh file or a level set (.vdb). `plot`: a .png
    to draw where the error lies (as --plot). Keywords: samples, seed, max_overestimate,
    max_overestimate_share, max_rms, max_tracer_overestimate, max_near_error,
    allow_sign_errors, scale, offset=(x, y, z)."""
    settings = _checked_keywords("check", options, _CHECK_KEYWORDS)
    if against is not None:
        settings["against"] = _os.fsdecode(_os.fspath(against))
    plot = "" if plot is None else _os.fsdecode(_os.fspath(plot))
    if isinstance(tile, Tile):
        report, found = _distile.check_tile(tile, "tile", "", settings, plot)
    else:
        path = _os.fsdecode(_os.fspath(tile))
        # The name as the file's bytes: any a Linux name may hold, as the command takes them.
        report, found = _distile.check_tile(load_tile(path), _os.fsencode(path), path, settings,
                                            plot)
    for warning in found:
        _warnings.warn(warning, stacklevel=2)
    return report


def render(scene, **options):
    """Render `scene` (a scene file, or a dict in the scene format; its relative paths from
    the current folder) as ``distile render`` does, to a Render: ``.image`` (linear RGB,
    (height, width, 3) float32), ``.aovs`` (with aovs=True), ``.stats``, ``.save(path)``.
    Keywords as the command's flags: width, height, spp, aovs, reference (True or "analytic":
    the analytic reference; "world" or "world-levelset": the world reference, which takes only
    width, height, aovs and, for "world-levelset", reference_voxels), iterations, epsilon,
    march, relaxation, filter, normal_filter, shell, shadows ("none", "full", "adaptive"),
    no_skip (a skip's name or a list of them: the work the renderer skips done anyway), and
    progress (a callable given the fraction done).
    What the command prints as warnings is told as UserWarnings and kept in ``.warnings``."""
    options = dict(options)
    progress = _progress("render", options.pop("progress", None))
    arguments = _checked_keywords("render", options, _RENDER_KEYWORDS)
    if arguments.get("reference", 0) is None:
        del arguments["reference"]
    if isinstance(scene, dict):
        result = _distile.render_scene_json(_json_text(scene, "scene"), ".", "scene", arguments,
                                            progress)
    else:
        result = _distile.render_scene_file(_os.fspath(scene), arguments, progress)
    if progress is not None:
        progress(1.0)
    for warning in result.warnings:
        _warnings.warn(warning, stacklevel=2)
    return result


def compare(a, b, difference=None, heatmap=None):
    """How far render `a` is from render `b` (usually the reference), as
    ``distile compare --json``: a dict of coverage mismatches, hit errors in texels (interior,
    silhouette, all), normal error and PSNR. Each is a Render made with aovs=True, or the
    image file of one written with its AOVs. `difference` and `heatmap`: where to write the
    difference image and the hit-error heat map (as -o and --heatmap; .png, .exr, .tif)."""
    return _distile.compare(a, b, "" if difference is None else _os.fspath(difference),
                            "" if heatmap is None else _os.fspath(heatmap))
