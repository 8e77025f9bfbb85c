"""The Python module against known answers and against the `distile` command."""

import gc
import os
import json
import re
import signal
import threading
import time
import warnings

import numpy as np
import pytest

import distile


def without_write_time(path):
    """The file's bytes, an EXR's capDate attribute (the time OpenEXR wrote it, to the second)
    blanked: the only bytes two writes of the same image may differ in."""
    data = path.read_bytes()
    return re.sub(rb"capDate\x00string\x00\x13\x00\x00\x00.{19}", b"capDate", data, flags=re.S)


@pytest.fixture(scope="module")
def chainmail():
    """The default chain mail: the acceptance example."""
    return distile.bake_chainmail()


def test_default_chainmail_is_a_256x256x16_float32_view(chainmail):
    array = chainmail.array
    assert array.shape == (16, 256, 256)
    assert array.dtype == np.float32
    assert chainmail.size == (256, 256, 16)
    metadata = chainmail.metadata
    assert metadata["size"] == "256x256x16"
    assert metadata["units"] == "texels"
    assert metadata["source"] == "chainmail"
    assert metadata["params"]["rings_per_row"] == 8
    assert metadata["band_texels"] == 16.0  # the default band is the tile depth
    assert len(metadata["hash"]) == 16
    # The bake's check against the analytic truth travels with the tile.
    assert metadata["check"].startswith("within tolerances: RMS ")


def test_array_is_a_read_only_view_that_keeps_the_tile_alive():
    tile = distile.bake_chainmail(size="32x32x8")
    first = tile.array
    second = tile.array
    assert not first.flags.owndata
    # Two views of the same memory: no copy was made.
    assert first.__array_interface__["data"][0] == second.__array_interface__["data"][0]
    with pytest.raises(ValueError):
        first[0, 0, 0] = 1.0
    expected = first.copy()
    del tile, second
    gc.collect()
    np.testing.assert_array_equal(first, expected)


def test_tiles_and_renders_cannot_be_made_empty():
    # An instance no constructor filled read unwritten memory: Render.__new__(Render).image
    # ended the interpreter with a segfault.
    for cls in (distile.Tile, distile.Render):
        with pytest.raises(TypeError, match="come from the module's functions"):
            cls.__new__(cls)
        with pytest.raises(TypeError):
            cls()


def test_the_only_classes_to_make_are_tiles_renders_and_errors():
    # _distile.CheckOptions.__new__(CheckOptions).samples read memory no constructor wrote:
    # options now go to the module as dicts, so no class is left whose instance could be empty
    # but Tile and Render (refused above and below).
    classes = {name for name in dir(distile._distile)
               if isinstance(getattr(distile._distile, name), type)}
    assert classes == {"Tile", "Render", "InputError", "FormatError", "InternalError"}
    tile = distile.bake_chainmail(size="32x32x8", rings_per_row=2, rows=2)
    with pytest.raises(TypeError, match="unexpected keyword 'sample'"):
        distile._distile.check_tile(tile, "tile", "", {"sample": 10})
    with pytest.raises(TypeError, match="unexpected keyword 'widht'"):
        distile._distile.render_scene_json("{}", ".", "scene", {"widht": 10})
    with pytest.raises(TypeError, match="keyword 'samples': '5' is not of its type"):
        distile._distile.check_tile(tile, "tile", "", {"samples": "5"})
    # A name Python cannot encode (a lone surrogate) is refused naming its keyword.
    with pytest.raises(TypeError, match="keyword 'march'"):
        distile.render({"objects": [{"mesh": "plane"}]}, march="sph\udcff")
    # A NUL inside a name is quoted as '?', not where the message ends.
    with pytest.raises(distile.InputError,
                       match=r"march: 'sph\?ere' is not accepted; accepted: sphere, "):
        distile.render({"objects": [{"mesh": "plane"}]}, march="sph\x00ere")
    report = distile.check(tile, samples=1000, seed=7)
    assert report["samples"] == 1000


def test_an_instance_made_by_the_base_classes_new_is_refused_not_read():
    # pybind11_object.__new__ (which the error of object.__new__ points to) made an instance no
    # constructor filled: reading it was a segfault.
    for cls, readers in ((distile.Tile, ("size", "array", "metadata")),
                         (distile.Render, ("image", "aovs", "stats", "warnings"))):
        empty = cls.__mro__[1].__new__(cls)
        for reader in readers:
            with pytest.raises(TypeError, match="is empty"):
                getattr(empty, reader)
        with pytest.raises(TypeError, match="is empty"):
            empty.save("never.exr")
    with pytest.raises(TypeError, match="is empty"):
        distile.check(distile.Tile.__mro__[1].__new__(distile.Tile))


def test_keywords_of_the_wrong_type_are_refused_by_name():
    scene = {"objects": [{"mesh": "plane"}]}
    for keyword, value in (("width", 128.0), ("width", True), ("aovs", "false"),
                           ("epsilon", "0.1"), ("march", 2)):
        with pytest.raises(TypeError, match=f"^render\\(\\): {keyword} must be"):
            distile.render(scene, **{keyword: value})
    with pytest.raises(distile.InputError, match="^width: 1099511627776 is not accepted"):
        distile.render(scene, width=2**40)
    tile = distile.bake_chainmail(size="32x32x8", rings_per_row=2, rows=2)
    for keyword, value in (("samples", 1000.0), ("samples", None), ("allow_sign_errors", "no"),
                           ("offset", (1, 2))):
        with pytest.raises(TypeError, match=f"^check\\(\\): {keyword} must be"):
            distile.check(tile, **{keyword: value})
    with pytest.raises(TypeError, match="^set_threads\\(\\): threads must be"):
        distile.set_threads(True)
    with pytest.raises(TypeError, match="^render\\(\\): width must be a whole number"):
        distile.render(scene, width=np.True_)
    # NumPy scalars and 0-d arrays are the numbers they hold; a NumPy bool is a bool.
    render = distile.render(scene, width=np.int32(16), height=np.array(12), aovs=np.True_,
                            epsilon=np.float32(0.02))
    assert render.image.shape == (12, 16, 3) and render.aovs
    report = distile.check(tile, samples=np.int64(1000), max_rms=np.array(0.5),
                           allow_sign_errors=np.False_)
    assert report["samples"] == 1000
    # What the types allow still reaches the library's own checks.
    with pytest.raises(distile.InputError, match="^width: 0 is not accepted"):
        distile.render(scene, width=0)
    cyclic = {"objects": []}
    cyclic["objects"].append(cyclic)
    with pytest.raises(distile.InputError, match="^scene: is not accepted; it holds itself"):
        distile.render(cyclic)


def test_bake_file_names_as_bytes_or_with_a_nul(source_dir):
    ring = source_dir / "data" / "meshes" / "ring.obj"
    assert distile.bake_mesh(bytes(ring), size="32x32x8").size == (32, 32, 8)
    with pytest.raises(distile.InputError, match="cannot hold a NUL character"):
        distile.bake_mesh("ring\0.obj", size="32x32x8")


def test_a_file_that_is_not_what_distile_reads_is_a_format_error_wherever_given(tmp_path):
    # bake_* gave InputError, check and load_tile FormatError, for the same kind of file.
    (tmp_path / "bad.vdb").write_bytes(b"not a level set")
    (tmp_path / "bad.png").write_bytes(b"GIF89a not a png")
    with pytest.raises(distile.FormatError, match="bad.vdb"):
        distile.bake_vdb(tmp_path / "bad.vdb", size="32x32x8")
    with pytest.raises(distile.FormatError, match="bad.png"):
        distile.bake_heightmap(tmp_path / "bad.png", size="32x32x8")
    tile = distile.bake_chainmail(size="64x64x16", rings_per_row=2, rows=2)
    with pytest.raises(distile.FormatError, match="bad.vdb"):
        distile.check(tile, against=tmp_path / "bad.vdb")


def test_file_names_that_are_not_utf8(tmp_path):
    # Linux names are any bytes: check() refused such a name (pybind11's "incompatible function
    # arguments"), and an error naming one came with an empty message.
    tile = distile.bake_grating(size="32x32x16", bars=2)
    name = os.fsdecode(bytes(tmp_path) + b"/grating\xff.exr")
    tile.save(name)
    assert distile.check(name)["passed"]
    with pytest.raises(distile.InputError, match=r"missing\\xff\.exr: no such file"):
        distile.load_tile(os.fsdecode(bytes(tmp_path) + b"/missing\xff.exr"))


def test_renders_tell_the_scenes_warnings(recwarn):
    # A tile that misses the check's tolerances: the command warns, and so does render().
    scene = {"objects": [{"mesh": "plane", "material": {
        "tile": {"bake": "chainmail", "size": "64x64x16"}}}]}
    render = distile.render(scene, width=16, height=12)
    assert any("misses distile check's tolerances" in warning for warning in render.warnings)
    told = [str(warning.message) for warning in recwarn.list]
    assert told == render.warnings
    assert recwarn.list[0].filename == __file__  # at the caller's line, not distile's


def test_bake_warnings_point_at_the_callers_line(recwarn):
    distile.bake_chainmail(size="64x64x16")  # misses the check's tolerances: warned
    assert recwarn.list, "expected a warning"
    assert all(warning.filename == __file__ for warning in recwarn.list)


def test_keywords_take_numpy_numbers_and_refuse_nan_by_name():
    # NaN reached the JSON reader as text ("FormatError: not valid JSON"), and NumPy numbers
    # were "not JSON serializable".
    tile = distile.bake_chainmail(size=np.array([32, 32, 8]), rings_per_row=np.int64(4))
    assert tile.size == (32, 32, 8)
    with pytest.raises(distile.InputError, match="ring_radius: nan is not accepted"):
        distile.bake_chainmail(ring_radius=float("nan"))
    with pytest.raises(distile.InputError, match="numbers must be finite"):
        distile.render({"objects": [{"mesh": "plane", "transform": {"scale": float("inf")}}]})
    # check()'s limits under its own keywords (they were named maxRmsTexels, ...).
    with pytest.raises(distile.InputError, match="^max_rms: nan is not accepted"):
        distile.check(tile, max_rms=float("nan"))


def test_grating_texels_take_the_analytic_distance():
    # 64x64x32, 4 bars of width 8 and height 6 per layer (edge radius 3), gap 1: the upper
    # layer's bars run along x centred at y = 8 + 16j, the layer spans z in [16.5, 22.5] (the
    # pair is centred at mid-depth). Texel (10, 7, 31) is centred at y = 7.5, over the flat top
    # of a bar (|y - 8| is below half the width minus the edge radius, 4 - 3): its distance is
    # z - 22.5 = 9. Texel (10, 7, 19), at the bar's mid-height z = 19.5, is 3 below its top and
    # bottom faces. Exact texels: the values at texel centres, not lowered.
    tile = distile.bake_grating(size="64x64x32", bars=4, exact_texels=True)
    assert tile.array[31, 7, 10] == pytest.approx(9.0, abs=1e-4)
    assert tile.array[19, 7, 10] == pytest.approx(-3.0, abs=1e-4)


def test_bake_gives_the_commands_tile(tmp_path, distile_command):
    run = distile_command("bake", "chainmail", "--size", "64x64x8", "--rings-per-row", "4",
                          "--rows", "6", "-o", tmp_path / "cli.exr")
    assert run.returncode == 0, run.stderr
    from_command = distile.load_tile(tmp_path / "cli.exr")
    from_python = distile.bake_chainmail(size=(64, 64, 8), rings_per_row=4, rows=6)
    assert from_python.metadata["hash"] == from_command.metadata["hash"]
    np.testing.assert_array_equal(from_python.array, from_command.array)


def test_bake_writes_the_commands_level_set(tmp_path, source_dir, distile_command):
    """vdb= writes the file `distile bake --vdb` writes, byte for byte (repeat= as --repeat),
    and the tile is the one the bake cache gives without it."""
    ring = source_dir / "data/meshes/ring.obj"
    cases = [
        (("chainmail", "--size", "64x64x8"),
         lambda vdb: distile.bake_chainmail(size="64x64x8", vdb=vdb),
         lambda: distile.bake_chainmail(size="64x64x8")),
        (("chainmail", "--size", "64x64x8", "--repeat", "2x3"),
         lambda vdb: distile.bake_chainmail(size=(64, 64, 8), vdb=vdb, repeat=(2, 3)),
         lambda: distile.bake_chainmail(size="64x64x8")),
        (("mesh", ring, "--size", "32x32x16"),
         lambda vdb: distile.bake_mesh(ring, size="32x32x16", vdb=vdb, repeat="1x2"),
         lambda: distile.bake_mesh(ring, size="32x32x16")),
    ]
    for index, (arguments, with_level_set, cached) in enumerate(cases):
        command_vdb = tmp_path / f"command{index}.vdb"
        repeat = ["--repeat", "1x2"] if arguments[0] == "mesh" else []
        run = distile_command("bake", *arguments, *repeat, "--vdb", command_vdb,
                              "-o", tmp_path / f"command{index}.exr")
        assert run.returncode == 0, run.stderr
        python_vdb = tmp_path / f"python{index}.vdb"
        with warnings.catch_warnings():  # a 64x64x8 chain mail misses the check's tolerances
            warnings.simplefilter("ignore")
            tile = with_level_set(python_vdb)
            np.testing.assert_array_equal(tile.array, cached().array)
        assert python_vdb.read_bytes() == command_vdb.read_bytes(), arguments
    # The level set round-trips into the same tile (placed where it was baked).
    exact = distile.bake_grating(size="32x32x16", bars=2, exact_texels=True,
                                 vdb=tmp_path / "grating.vdb")
    again = distile.bake_vdb(tmp_path / "grating.vdb", size="32x32x16", scale=1.0,
                             offset=(0, 0, 0), exact_texels=True)
    np.testing.assert_array_equal(again.array, exact.array)


def test_a_refused_level_set_bake_writes_nothing(tmp_path):
    with pytest.raises(distile.InputError, match="repeat: needs vdb=FILE"):
        distile.bake_grating(size="32x32x16", bars=2, repeat=(2, 2))
    with pytest.raises(distile.InputError, match=r"vdb: '.*/g\.png' is not accepted; .* \.vdb"):
        distile.bake_grating(size="32x32x16", bars=2, vdb=tmp_path / "g.png")
    with pytest.raises(distile.InputError, match="vdb: .* folder .* does not exist"):
        distile.bake_grating(size="32x32x16", bars=2, vdb=tmp_path / "no" / "g.vdb")
    # Repeats beyond the level set's limits are refused before the bake, as --repeat.
    with pytest.raises(distile.InputError, match="repeat: 65x1 is not accepted"):
        distile.bake_grating(size="32x32x16", bars=2, vdb=tmp_path / "g.vdb", repeat=(65, 1))
    # A bad band is told under its own key, not as a repeat the band makes too large.
    with pytest.raises(distile.InputError, match="bake grating: band: 0.5 texels is not accepted"):
        distile.bake_grating(size="32x32x16", bars=2, band=0.5, vdb=tmp_path / "g.vdb")
    with pytest.raises(distile.InputError, match="repeat: '2x' is not accepted"):
        distile.bake_grating(size="32x32x16", bars=2, vdb=tmp_path / "g.vdb", repeat="2x")
    with pytest.raises(TypeError, match="repeat must be two whole numbers"):
        distile.bake_grating(size="32x32x16", bars=2, vdb=tmp_path / "g.vdb", repeat=2)
    # A bake that fails after the file was checked leaves no file behind.
    with pytest.raises(distile.InputError, match="bars"):
        distile.bake_grating(size="32x32x16", bars=0, vdb=tmp_path / "g.vdb")
    assert list(tmp_path.iterdir()) == []


def test_save_and_load_round_trip(tmp_path):
    tile = distile.bake_grating(size="32x32x16", bars=2)
    tile.save(tmp_path / "grating.exr")
    loaded = distile.load_tile(tmp_path / "grating.exr")
    np.testing.assert_array_equal(loaded.array, tile.array)
    assert loaded.metadata == tile.metadata
    tile.save(tmp_path / "half.exr", half=True)
    half = distile.load_tile(tmp_path / "half.exr")
    # Half floats keep 11 significant bits, rounded down: below the float, by less than 2^-10
    # relative (2^-24 absolute below the smallest normal half).
    assert (half.array <= tile.array).all()
    np.testing.assert_allclose(half.array, tile.array, rtol=2.0**-10, atol=2.0**-24)
    tile.save_png(tmp_path / "grating.png", bits=8)
    assert (tmp_path / "grating.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_tile_pictures_are_the_commands(tmp_path, distile_command):
    """save_preview as `distile preview`, save_view as `distile view`, save_png(signed=True) as
    --png16-signed: the same files."""
    run = distile_command("bake", "grating", "--size", "32x32x16", "--bars", "2",
                          "-o", tmp_path / "grating.exr", "--png16-signed",
                          tmp_path / "command_signed.png")
    assert run.returncode == 0, run.stderr
    for arguments in [("preview", tmp_path / "grating.exr", "-o", tmp_path / "command.png"),
                      ("view", tmp_path / "grating.exr", "-o", tmp_path / "command.html",
                       "--object", "sphere", "--sphere-depth", "0.05", "--uv-scale", "2", "3",
                       "--open-floor")]:
        run = distile_command(*arguments)
        assert run.returncode == 0, run.stderr
    tile = distile.load_tile(tmp_path / "grating.exr")
    tile.save_preview(tmp_path / "python.png")
    tile.save_view(tmp_path / "python.html", object="sphere", sphere_depth=0.05, uv_scale=(2, 3),
                   open_floor=True, title="grating.exr")
    tile.save_png(tmp_path / "python_signed.png", signed=True)
    for name in ["python.png", "python.html", "python_signed.png"]:
        command = tmp_path / name.replace("python", "command")
        assert (tmp_path / name).read_bytes() == command.read_bytes(), name
    before = sorted(tmp_path.iterdir())
    with pytest.raises(distile.InputError, match="save_png: signed: .* 16-bit"):
        tile.save_png(tmp_path / "s.png", bits=8, signed=True)
    with pytest.raises(distile.InputError, match="save_preview: .* ends in .png"):
        tile.save_preview(tmp_path / "p.jpg")
    with pytest.raises(distile.InputError, match="object: 'cube' is not accepted"):
        tile.save_view(tmp_path / "v.html", object="cube")
    with pytest.raises(distile.InputError, match="uv_scale: 0 is not accepted"):
        tile.save_view(tmp_path / "v.html", uv_scale=(0, 1))
    assert sorted(tmp_path.iterdir()) == before


def test_errors_are_value_errors_with_the_commands_messages(tmp_path, distile_command):
    with pytest.raises(distile.InputError, match="size") as raised:
        distile.bake_chainmail(size="1x64x8")
    assert isinstance(raised.value, ValueError)
    # The command refuses the same value for the same reason.
    run = distile_command("bake", "chainmail", "--size", "1x64x8", "-o", tmp_path / "t.exr")
    assert run.returncode == 2
    problem = str(raised.value).split("size: ", 1)[1]
    assert problem in run.stderr
    with pytest.raises(distile.InputError, match="accepted: chainmail, grating"):
        distile.bake("rivets")
    with pytest.raises(distile.InputError, match="missing.exr: no such file"):
        distile.load_tile(tmp_path / "missing.exr")
    # The path as given, not the temporary the image would have been written to first.
    bare = {"objects": [{"mesh": "plane", "material": {"color": [0.8, 0.8, 0.8]}}]}
    with pytest.raises(distile.InputError, match=r"/x\.txt: image extension '\.txt'"):
        distile.render(bare, width=8, height=6).save(tmp_path / "x.txt")
    assert list(tmp_path.glob("*x*.txt")) == []
    (tmp_path / "not_a_tile.exr").write_bytes(b"not an image")
    with pytest.raises(distile.FormatError):
        distile.load_tile(tmp_path / "not_a_tile.exr")
    with pytest.raises(distile.InputError, match="unknown field; accepted here"):
        distile.render({"objects": [{"mesh": "plane", "materal": {}}]})
    with pytest.raises(distile.InputError, match="march: 'walk' is not accepted"):
        distile.render({"objects": [{"mesh": "plane"}]}, width=8, height=8, march="walk")
    with pytest.raises(distile.InputError, match="spp"):
        distile.render({"objects": [{"mesh": "plane"}]}, width=8, height=8, spp=0)


def test_options_that_would_be_ignored_are_refused(source_dir):
    # fit=False alone used to bake the fitted tile; the European weave has no small rings.
    with pytest.raises(distile.InputError, match="fit: false needs the explicit placement"):
        distile.bake_mesh(source_dir / "data/meshes/ring.obj", size="32x32x8", fit=False)
    with pytest.raises(distile.InputError, match="small_ring_radius: only for"):
        distile.bake_chainmail(size="64x64x8", small_ring_radius=0.2)


def test_render_is_byte_identical_to_the_commands(tmp_path, source_dir, distile_command):
    scene = source_dir / "data" / "scenes" / "sheet.json"
    run = distile_command("render", scene, "-o", tmp_path / "cli.png", "--aovs", "--width", 96,
                          "--height", 72)
    assert run.returncode == 0, run.stderr
    rendered = distile.render(scene, width=96, height=72, aovs=True)
    assert rendered.image.shape == (72, 96, 3)
    assert rendered.image.dtype == np.float32
    assert set(rendered.aovs) == {"depth", "normal", "iterations", "shadow_samples",
                                  "shadow_map_samples", "curvature", "texel_scale"}
    assert rendered.stats["rays"] == 96 * 72
    # Every surface the sheet's rays hit is the tiled sheet, and every one of them converged.
    assert rendered.stats["detail_hits"] == rendered.stats["base_hits"] > 0
    assert rendered.stats["converged"] == rendered.stats["detail_hits"]
    rendered.save(tmp_path / "py.png")
    for suffix in [".png", ".depth.exr", ".normal.png", ".iterations.png",
                   ".shadow_samples.png", ".shadow_map_samples.png", ".curvature.png",
                   ".texel_scale.exr"]:
        assert without_write_time(tmp_path / ("py" + suffix)) == \
            without_write_time(tmp_path / ("cli" + suffix)), suffix
    # The same scene as a dict (it names no file) renders the same image.
    from_dict = distile.render(json.loads(scene.read_text()), width=96, height=72)
    np.testing.assert_array_equal(from_dict.image, rendered.image)
    # Against itself: no mismatch, identical images (PSNR infinite: null in JSON, None here).
    for a, b in [(rendered, rendered), (tmp_path / "py.png", tmp_path / "cli.png")]:
        report = distile.compare(a, b)
        assert report["coverage_mismatches"] == 0
        assert report["psnr_db"] is None
        assert report["interior"]["hit_error_max"] == 0.0
        assert report["both_hit"] + report["coverage_mismatches"] > 0
    # The 8-bit PNG against the float image it was written from: quantisation only.
    assert distile.compare(rendered, tmp_path / "cli.png")["psnr_db"] > 40
    # Anything else is a TypeError naming the argument and what it takes.
    with pytest.raises(TypeError, match="b must be a distile.Render or the path .* got NoneType"):
        distile.compare(rendered, None)
    with pytest.raises(TypeError, match="a must be .* got int"):
        distile.compare(3, rendered)


def test_world_reference_is_the_commands(tmp_path, distile_command):
    """reference="world": the command's --reference world, file for file, and the truth the
    curved shell's render is measured against."""
    scene = {"objects": [{"mesh": "sphere", "material": {
        "tile": {"bake": "grating", "size": "32x32x16", "bars": 2}, "uv_scale": [4, 2],
        "depth": 0.08}}]}
    (tmp_path / "scene.json").write_text(json.dumps(scene))
    run = distile_command("render", tmp_path / "scene.json", "-o", tmp_path / "command.png",
                          "--width", "64", "--height", "48", "--aovs", "--reference", "world")
    assert run.returncode == 0, run.stderr
    with warnings.catch_warnings():  # a 32-texel grating misses the check's tolerances
        warnings.simplefilter("ignore")
        reference = distile.render(scene, width=64, height=48, aovs=True, reference="world")
        render = distile.render(scene, width=64, height=48, aovs=True)
    assert sorted(reference.aovs) == ["depth", "normal", "texel_scale"]
    reference.save(tmp_path / "python.png")
    written = sorted(path.name for path in tmp_path.glob("python*"))
    assert written == ["python.depth.exr", "python.normal.png", "python.png",
                       "python.texel_scale.exr"]
    for name in written:
        command = tmp_path / name.replace("python", "command")
        assert without_write_time(tmp_path / name) == without_write_time(command), name
    # The curved shell's render lies within a few hundredths of a texel of it (the interior
    # pixels; 0.014 measured), and misses or hits alone at a few silhouette pixels.
    comparison = distile.compare(render, reference)
    assert comparison["interior"]["pixels"] > 400
    assert comparison["interior"]["hit_error_mean"] < 0.05
    assert comparison["coverage_mismatches"] < 20


def test_no_skip_does_the_work_the_command_does(tmp_path, source_dir, distile_command):
    """no_skip as --no-skip: the same image (shell culling changes none) for more shells
    traced."""
    scene = source_dir / "data/scenes/torus_on_sheet.json"
    run = distile_command("render", scene, "-o", tmp_path / "command.png", "--width", "64",
                          "--height", "48", "--no-skip", "shell-culling", "--no-skip",
                          "unlit-shadows")
    assert run.returncode == 0, run.stderr
    culled = distile.render(scene, width=64, height=48)
    every = distile.render(scene, width=64, height=48, no_skip=["shell-culling", "unlit-shadows"])
    every.save(tmp_path / "python.png")
    assert (tmp_path / "python.png").read_bytes() == (tmp_path / "command.png").read_bytes()
    np.testing.assert_array_equal(every.image, culled.image)
    assert every.stats["shells_traced"] > culled.stats["shells_traced"]
    with pytest.raises(distile.InputError, match="no_skip: 'x' is not accepted; accepted: "):
        distile.render(scene, width=8, height=8, no_skip="x")


def test_world_reference_refuses_what_it_would_ignore():
    scene = {"objects": [{"mesh": "sphere"}]}
    for keyword, value in [("iterations", 8), ("spp", 2), ("shadows", "none"), ("shell", "planar")]:
        with pytest.raises(distile.InputError, match=f"{keyword}: does not apply to "
                                                     "reference='world'"):
            distile.render(scene, width=8, height=8, reference="world", **{keyword: value})
    with pytest.raises(distile.InputError, match="reference_voxels: applies to "
                                                 "reference='world-levelset' only"):
        distile.render(scene, width=8, height=8, reference=True, reference_voxels=2)
    with pytest.raises(distile.InputError, match=r"reference_voxels: 100 is not accepted"):
        distile.render(scene, width=8, height=8, reference="world-levelset",
                       reference_voxels=100)
    with pytest.raises(distile.InputError, match="reference: 'worlds' is not accepted"):
        distile.render(scene, width=8, height=8, reference="worlds")
    with pytest.raises(TypeError, match="reference must be True, False"):
        distile.render(scene, width=8, height=8, reference=3)
    # False is no reference: the tiles' render.
    assert distile.render(scene, width=8, height=8, reference=False).stats["rays"] == 64


def test_check_matches_the_commands_report(tmp_path, distile_command):
    tile = distile.bake_chainmail(size="64x64x8", rings_per_row=4, rows=6)
    tile.save(tmp_path / "chain.exr")
    run = distile_command("check", tmp_path / "chain.exr", "--json", "--samples", 20000)
    from_command = json.loads(run.stdout)
    # Exit 0 when it passes, 1 when a tolerance is exceeded.
    assert run.returncode == (0 if from_command["passed"] else 1), run.stderr
    report = distile.check(tmp_path / "chain.exr", samples=20000)
    assert report == from_command
    in_memory = distile.check(tile, samples=20000)
    assert in_memory["rms"] == from_command["rms"]
    assert in_memory["failures"] == from_command["failures"]
    assert in_memory["against"].startswith("analytic chainmail")
    with pytest.raises(distile.InputError, match="samples"):
        distile.check(tile, samples=0)


def test_check_plots_and_compare_images_are_the_commands(tmp_path, distile_command):
    """check(plot=) as --plot, compare(difference=, heatmap=) as -o and --heatmap: the same
    files; their paths checked before the work, nothing written when refused."""
    tile = distile.bake_grating(size="32x32x16", bars=2)
    tile.save(tmp_path / "grating.exr")
    run = distile_command("check", tmp_path / "grating.exr", "--plot", tmp_path / "command.png")
    assert run.returncode == 0, run.stderr
    report = distile.check(tmp_path / "grating.exr", plot=tmp_path / "python.png")
    assert report["plot"] == str(tmp_path / "python.png")
    assert (tmp_path / "python.png").read_bytes() == (tmp_path / "command.png").read_bytes()
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps({"objects": [{"mesh": "sphere", "material": {
        "tile": {"bake": "grating", "size": "32x32x16", "bars": 2}, "depth": 0.08}}]}))
    for name, shell in [("a", "curved"), ("b", "planar")]:
        run = distile_command("render", scene, "-o", tmp_path / f"{name}.png", "--width", "48",
                              "--height", "32", "--aovs", "--shell", shell)
        assert run.returncode == 0, run.stderr
    run = distile_command("compare", tmp_path / "a.png", tmp_path / "b.png", "--json",
                          "-o", tmp_path / "command_diff.png", "--heatmap",
                          tmp_path / "command_heat.png")
    assert run.returncode == 0, run.stderr
    comparison = distile.compare(tmp_path / "a.png", tmp_path / "b.png",
                                 difference=tmp_path / "python_diff.png",
                                 heatmap=tmp_path / "python_heat.png")
    from_command = json.loads(run.stdout)
    assert comparison["coverage_mismatches"] == from_command["coverage_mismatches"]
    assert comparison["difference"] == str(tmp_path / "python_diff.png")
    for kind in ["diff", "heat"]:
        assert ((tmp_path / f"python_{kind}.png").read_bytes() ==
                (tmp_path / f"command_{kind}.png").read_bytes())
    before = sorted(tmp_path.iterdir())
    with pytest.raises(distile.InputError, match="check: plot: .* the plot is a PNG"):
        distile.check(tile, plot=tmp_path / "plot.jpg")
    with pytest.raises(distile.InputError, match="check: plot: .* folder .* does not exist"):
        distile.check(tile, plot=tmp_path / "no" / "plot.png")
    with pytest.raises(distile.InputError, match="compare: difference: .*'.txt' is not accepted"):
        distile.compare(tmp_path / "a.png", tmp_path / "b.png", difference=tmp_path / "d.txt")
    # A comparison that fails writes neither image.
    with pytest.raises(distile.InputError, match="B: image .*missing.png does not exist"):
        distile.compare(tmp_path / "a.png", tmp_path / "missing.png",
                        difference=tmp_path / "d.png", heatmap=tmp_path / "h.png")
    assert sorted(tmp_path.iterdir()) == before


def test_renders_release_the_gil():
    # While one thread renders, this one keeps running Python: with the GIL held for the whole
    # render it could not run a single iteration between the render's start and end. The render
    # is large enough to last well over 0.05 s (about 0.3 s on two 2.4 GHz cores; at 160 x 120
    # with 4 samples it once took 0.046 s).
    window = {}

    def render():
        window["start"] = time.perf_counter()
        distile.render({"objects": [{"mesh": "sphere", "material": {
            "tile": {"bake": "grating", "size": "32x32x16", "bars": 2}}}]},
            width=320, height=240, spp=8)
        window["end"] = time.perf_counter()

    worker = threading.Thread(target=render)
    ticks = []
    worker.start()
    while worker.is_alive():
        ticks.append(time.perf_counter())
        time.sleep(0.001)
    worker.join()
    during = [t for t in ticks if window["start"] < t < window["end"]]
    assert window["end"] - window["start"] > 0.05
    assert len(during) >= 10


def test_progress_reports_bakes_and_renders_and_can_end_them(tmp_path, source_dir):
    """progress=callable: the fraction done, rising, every 50 ms at most, then 1.0 once done;
    raising in it ends the work with that error and writes nothing. The work is long enough for
    several reports (the bake about 1 s, the render 0.3 s on two cores)."""
    for work in [
            lambda report: distile.bake_grating(size="256x256x32", bars=8,
                                                vdb=tmp_path / "g.vdb", progress=report),
            lambda report: distile.render(source_dir / "data/scenes/torus_on_sheet.json",
                                          width=640, height=512, progress=report)]:
        fractions = []
        work(fractions.append)
        assert len(fractions) >= 3
        assert fractions == sorted(fractions)
        assert 0.0 <= fractions[0] < 1.0 and fractions[-1] == 1.0
    (tmp_path / "g.vdb").unlink()

    def enough(fraction):
        if fraction > 0.0:
            raise ArithmeticError("enough")

    with pytest.raises(ArithmeticError, match="enough"):
        distile.bake_grating(size="256x256x32", bars=8, vdb=tmp_path / "g.vdb", progress=enough)
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(TypeError, match="progress must be a callable"):
        distile.render({"objects": [{"mesh": "plane"}]}, width=8, height=8, progress=1)


def seconds_to_interrupt(work, after):
    """Sends this process SIGINT (Ctrl-C) `after` seconds into `work`, which must raise
    KeyboardInterrupt; returns the seconds from the signal to the raise."""
    sent = []

    def interrupt():
        sent.append(time.monotonic())
        os.kill(os.getpid(), signal.SIGINT)

    timer = threading.Timer(after, interrupt)
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            work()
        raised = time.monotonic()
    finally:
        timer.cancel()
    assert len(sent) == 1
    return raised - sent[0]


def test_ctrl_c_ends_a_bake_at_its_next_report(tmp_path):
    # A chain mail of 512 x 512 x 32 texels with its level set (always baked; filling the level
    # set alone takes about 2 s on two cores, reporting every 50-70 ms). Ctrl-C 0.3 s in raises
    # KeyboardInterrupt at the bake's next report, and no file is left.
    bake = lambda: distile.bake_chainmail(size="512x512x32", vdb=tmp_path / "chain.vdb")
    assert seconds_to_interrupt(bake, after=0.3) < 1.0
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_ends_the_bake_of_a_renders_tile(monkeypatch):
    # Without a cache the scene's chain mail of 512 x 512 x 32 texels is baked (its level set
    # alone about 2 s on two cores) before any pixel: Ctrl-C 0.3 s in ends that bake.
    monkeypatch.setenv("DISTILE_CACHE", "off")
    scene = {"objects": [{"mesh": "plane", "material": {
        "tile": {"bake": "chainmail", "size": "512x512x32"}}}]}
    assert seconds_to_interrupt(lambda: distile.render(scene, width=8, height=8),
                                after=0.3) < 1.0


def test_ctrl_c_ends_a_render_at_its_next_block_of_pixels(source_dir):
    # A render of 2^24 camera samples of the torus on the sheet (several seconds on two cores),
    # its tile baked beforehand. Ctrl-C (SIGINT) half a second in raises KeyboardInterrupt as the
    # render finishes its block of pixels, not when its last pixel is done.
    scene = source_dir / "data" / "scenes" / "torus_on_sheet.json"
    distile.render(scene, width=32, height=32, shadows="none")  # the tile, into the cache
    assert seconds_to_interrupt(lambda: distile.render(scene, width=1024, height=1024, spp=16),
                                after=0.5) < 1.0
