// The compiled part of the Python package `distile` (python/distile/__init__.py is the rest):
// bake recipes, tiles as NumPy views, renders, checks and comparisons, each through the library
// function the command calls. The GIL is released while the libraries work; they never call
// back into Python, except that a render takes the GIL between blocks of pixels to let Python
// handle a pending signal (Ctrl-C).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <system_error>
#include <vector>

#include "check/reports.h"
#include "check/tile_check.h"
#include "common/atomic_file.h"
#include "common/error.h"
#include "common/fnv1a.h"
#include "common/input_file.h"
#include "common/size3.h"
#include "render/compare.h"
#include "render/render_files.h"
#include "render/renderer.h"
#include "render/world_reference.h"
#include "sampler/tile.h"
#include "sampler/tile_io.h"
#include "scene/scene_file.h"
#include "view/contact_sheet.h"
#include "view/tile_page.h"

namespace py = pybind11;
namespace fs = std::filesystem;

namespace distile::python {

namespace {

/// A tile as Python holds it: shared with every NumPy view of it, which keeps it alive.
struct PyTile {
    std::shared_ptr<const Tile> tile;
};

/// A render as Python holds it.
struct PyRender {
    std::shared_ptr<const RenderResult> result;
    bool worldReference = false;  ///< its AOVs only kWorldReferenceAovs (render/world_reference.h)
};

/// The tile a Python Tile holds. pybind11_object.__new__ (the base's, which the module's own
/// __new__ cannot stop) makes an instance no constructor filled: refused, not read.
template <class Held>
const Held& filled(py::handle self, const char* message) {
    if (!py::isinstance<Held>(self)) throw py::type_error(message);
    auto* instance = reinterpret_cast<py::detail::instance*>(self.ptr());
    const py::detail::value_and_holder held =
        instance->get_value_and_holder(py::detail::get_type_info(typeid(Held)), false);
    if (!held || !held.holder_constructed()) throw py::type_error(message);
    return *held.value_ptr<Held>();
}

const Tile& tileOf(py::handle self) {
    const PyTile& held =
        filled<PyTile>(self, "this distile.Tile is empty: tiles come from load_tile and bake_*");
    return *held.tile;
}

/// The Python Render (see tileOf).
const PyRender& pyRenderOf(py::handle self) {
    return filled<PyRender>(self, "this distile.Render is empty: renders come from render()");
}

/// The render a Python Render holds.
const RenderResult& renderOf(py::handle self) {
    return *pyRenderOf(self).result;
}

/// The names of the AOVs of kAovFiles a render holds: a world reference's, else all (empty).
std::span<const char* const> aovNames(const PyRender& render) {
    if (render.worldReference) return kWorldReferenceAovs;
    return {};
}

/// `values` (row-major, `channels` floats per element) as a read-only NumPy array of `shape`
/// that keeps `owner` alive instead of copying.
py::array readOnlyView(const float* values, std::vector<py::ssize_t> shape, py::handle owner) {
    std::vector<py::ssize_t> strides(shape.size());
    py::ssize_t stride = sizeof(float);
    for (std::size_t axis = shape.size(); axis-- > 0;) {
        strides[axis] = stride;
        stride *= shape[axis];
    }
    py::array view(py::dtype::of<float>(), shape, strides, values, owner);
    view.attr("setflags")(py::arg("write") = false);
    return view;
}

/// An image (linear RGB, row 0 at the top) as a read-only (height, width, 3) float32 view.
py::array imageView(const Image& image, py::handle owner) {
    return readOnlyView(reinterpret_cast<const float*>(image.rgbLinear.data()),
                        {image.height, image.width, 3}, owner);
}

py::object jsonValue(const std::string& text) {
    return py::module_::import("json").attr("loads")(text);
}

/// The value the library names by `name` among `values` (named by `nameOf`), or InputError
/// naming `field` with the accepted names.
template <class Value, std::size_t N>
Value named(const std::string& name, const Value (&values)[N], const char* (*nameOf)(Value),
            const std::string& field) {
    std::string accepted;
    for (const Value value : values) {
        if (name == nameOf(value)) return value;
        accepted += std::string(accepted.empty() ? "" : ", ") + nameOf(value);
    }
    // Quoted as the readers quote input: a NUL would end the message where Python reads it.
    throw InputError::inField(field,
                              "'" + quotedInput(name) + "' is not accepted; accepted: " + accepted);
}

/// Thrown through a library's work when Python raised in its progress callback: a pending
/// signal's handler (Ctrl-C: KeyboardInterrupt) or the caller's `progress`; the Python error is
/// set.
struct PythonRaised {};

/// A progress callback that, at most every 50 ms (taking the GIL may wait for another Python
/// thread), lets Python handle pending signals and calls `report` (a callable, or None) with the
/// fraction done. Called on the thread that started the work (with the GIL released); a handler
/// or `report` that raises ends the work (PythonRaised). `report` must outlive the work; the
/// callback holds its address, not a reference count (copies of it are made without the GIL).
ProgressCallback pythonProgress(const py::object& report) {
    return
        [report = &report, last = std::chrono::steady_clock::now()](double fractionDone) mutable {
            const auto now = std::chrono::steady_clock::now();
            if (now - last < std::chrono::milliseconds(50)) return;
            last = now;
            py::gil_scoped_acquire acquired;
            if (PyErr_CheckSignals() != 0) throw PythonRaised{};
            if (report->is_none()) return;
            try {
                (*report)(fractionDone);
            } catch (py::error_already_set& error) {
                error.restore();
                throw PythonRaised{};
            }
        };
}

/// Runs `work` (which releases the GIL) and turns PythonRaised into the Python error it left.
template <class Work>
auto raisingPythonErrors(const Work& work) {
    try {
        return work();
    } catch (const PythonRaised&) {
        throw py::error_already_set();
    }
}

/// The tile of a bake recipe (scene/scene_file.h bakeRecipeTile) and the warnings of its bake,
/// reporting to `progress` (pythonProgress).
std::pair<PyTile, std::vector<std::string>> bakeRecipe(const std::string& recipeJson,
                                                       const std::string& name,
                                                       const py::object& progress) {
    std::vector<std::string> warnings;
    const auto tile = raisingPythonErrors([&] {
        const ProgressCallback report = pythonProgress(progress);
        py::gil_scoped_release released;
        TileCache tiles;
        return bakeRecipeTile(
            recipeJson, fs::path("."), name, tiles,
            [&](const std::string& warning) { warnings.push_back(warning); }, report);
    });
    return {PyTile{tile}, warnings};
}

/// Throws InputError naming `shownAs` unless `file` ends in `extension` (any case); `what` says
/// why.
void requireExtension(const fs::path& file, const std::string& shownAs, const char* extension,
                      const char* what) {
    if (lowerExtension(file) != extension) {
        throw InputError(shownAs + ": '" + file.string() + "' is not accepted; " + what +
                         ", which ends in " + extension);
    }
}

/// Tells `warning` to Python as a UserWarning (the GIL held); an error if warnings are errors.
void warnPython(const std::string& warning) {
    if (PyErr_WarnEx(PyExc_UserWarning, warning.c_str(), 1) != 0) throw py::error_already_set();
}

/// bakeRecipe with the recipe's level set written to `vdbFile`, tiled `repeatX` x `repeatY` times
/// (as `distile bake --vdb --repeat`): the file checked before the bake and written once the bake
/// succeeded (common/atomic_file.h). Always bakes: the bake cache holds tiles only.
std::pair<PyTile, std::vector<std::string>> bakeRecipeWithLevelSet(const std::string& recipeJson,
                                                                   const std::string& name,
                                                                   const fs::path& vdbFile,
                                                                   int repeatX, int repeatY,
                                                                   const py::object& progress) {
    std::vector<std::string> warnings;
    const auto tile = raisingPythonErrors([&] {
        const ProgressCallback report = pythonProgress(progress);
        py::gil_scoped_release released;
        requireExtension(vdbFile, name + ": vdb", ".vdb", "the level set is an OpenVDB file");
        OutputFiles outputs;
        const fs::path temporary = outputs.add(vdbFile, name + ": vdb");
        RecipeLevelSet baked = bakeRecipeLevelSet(
            recipeJson, fs::path("."), name, repeatX, repeatY,
            [&](const std::string& warning) { warnings.push_back(warning); }, report);
        baked.levelSet.save(temporary);
        outputs.commit();
        return baked.tile;
    });
    return {PyTile{tile}, warnings};
}

/// The options of `distile render` under their flags' names, as the command fills them.
struct PyRenderArguments {
    std::optional<int> width, height, spp;
    bool aovs = false;
    /// "analytic", "world" or "world-levelset" (the package's reference=True: "analytic").
    std::optional<std::string> reference;
    std::optional<double> referenceVoxels;
    std::optional<int> iterations;
    std::optional<float> epsilon;
    std::optional<std::string> march;
    std::optional<float> relaxation;
    std::optional<std::string> filter;
    std::optional<std::string> normalFilter;
    std::optional<std::string> shell;
    std::optional<std::string> shadows;
    std::vector<std::string> noSkip;  ///< --no-skip: the skips switched off (RenderSkipSwitch)
};

/// A member of T that fromKeywords sets from the keyword `name`.
template <class T>
struct KeywordMember {
    const char* name;
    std::function<void(T&, py::handle)> set;
};

template <class T, class M>
KeywordMember<T> member(const char* name, M T::*field) {
    return {name, [field](T& target, py::handle value) { target.*field = value.cast<M>(); }};
}

/// A T with its defaults, each member of `members` named in `keywords` set from it (checked by
/// the package's _keyword before). The option structs are not Python classes: an instance of one
/// made by __new__ alone would read memory no constructor wrote.
template <class T>
T fromKeywords(const py::dict& keywords, std::initializer_list<KeywordMember<T>> members) {
    T target{};
    for (const auto& [key, value] : keywords) {
        const std::string name = py::str(key);
        const auto found = std::find_if(members.begin(), members.end(),
                                        [&](const KeywordMember<T>& m) { return name == m.name; });
        if (found == members.end()) throw py::type_error("unexpected keyword '" + name + "'");
        try {
            found->set(target, value);
        } catch (const py::cast_error&) {
            throw py::type_error("keyword '" + name + "': " + std::string(py::repr(value)) +
                                 " is not of its type");
        }
    }
    return target;
}

PyRenderArguments renderArguments(const py::dict& keywords) {
    using A = PyRenderArguments;
    return fromKeywords<A>(
        keywords,
        {member("width", &A::width), member("height", &A::height), member("spp", &A::spp),
         member("aovs", &A::aovs), member("reference", &A::reference),
         member("reference_voxels", &A::referenceVoxels), member("iterations", &A::iterations),
         member("epsilon", &A::epsilon), member("march", &A::march),
         member("relaxation", &A::relaxation), member("filter", &A::filter),
         member("normal_filter", &A::normalFilter), member("shell", &A::shell),
         member("shadows", &A::shadows), member("no_skip", &A::noSkip)});
}

TileCheckOptions checkOptions(const py::dict& keywords) {
    using O = TileCheckOptions;
    return fromKeywords<O>(
        keywords, {member("against", &O::against), member("samples", &O::samples),
                   member("seed", &O::seed), member("max_overestimate", &O::maxOverestimateTexels),
                   member("max_overestimate_share", &O::maxOverestimateShare),
                   member("max_rms", &O::maxRmsTexels),
                   member("max_tracer_overestimate", &O::maxTracerOverestimateTexels),
                   member("max_near_error", &O::maxNearErrorTexels),
                   member("allow_sign_errors", &O::allowSignErrors), member("scale", &O::meshScale),
                   member("offset", &O::meshOffsetTexels)});
}

RenderOptions renderOptions(const PyRenderArguments& arguments, const ImageSettings& image) {
    RenderOptions options;
    options.width = arguments.width.value_or(image.width);
    options.height = arguments.height.value_or(image.height);
    options.samplesPerPixel = arguments.spp.value_or(image.samplesPerPixel);
    options.outputAovs = arguments.aovs;
    options.reference = arguments.reference.has_value();
    if (arguments.iterations) options.march.maxIterations = *arguments.iterations;
    if (arguments.epsilon) options.march.epsilonTexels = *arguments.epsilon;
    if (arguments.relaxation) options.march.relaxation = *arguments.relaxation;
    if (arguments.march)
        options.march.method = named(*arguments.march, kMarchMethods, marchMethodName, "march");
    if (arguments.filter)
        options.filter = named(*arguments.filter, kFilterKinds, filterKindName, "filter");
    if (arguments.normalFilter)
        options.normalFilter =
            named(*arguments.normalFilter, kFilterKinds, filterKindName, "normal_filter");
    if (arguments.shell)
        options.shellMapping = named(*arguments.shell, kShellMappings, shellMappingName, "shell");
    if (arguments.shadows)
        options.shadowFilter =
            named(*arguments.shadows, kShadowFilters, shadowFilterName, "shadows");
    options.selfShadows = options.shadowFilter != ShadowFilter::None;
    for (const std::string& name : arguments.noSkip) {
        const auto skip = std::ranges::find_if(
            kRenderSkipSwitches, [&](const RenderSkipSwitch& known) { return name == known.name; });
        if (skip == std::end(kRenderSkipSwitches)) {
            std::string accepted;
            for (const RenderSkipSwitch& known : kRenderSkipSwitches)
                accepted += std::string(accepted.empty() ? "" : ", ") + known.name;
            throw InputError("no_skip: '" + quotedInput(name) +
                             "' is not accepted; accepted: " + accepted);
        }
        options.skips.*skip->enabled = false;
    }
    return options;
}

/// A library's error about a RenderOptions member under the keyword that filled it.
InputError underRenderKeyword(const InputError& error) {
    const InputError shown = shownUnder(error, {{"samplesPerPixel", "spp"},
                                                {"outputAovs", "aovs"},
                                                {"march.maxIterations", "iterations"},
                                                {"march.epsilonTexels", "epsilon"},
                                                {"march.relaxation", "relaxation"}});
    return shown.field() != error.field() ? shown : underSceneJsonPath(error);
}

/// The world reference's options of `arguments` (reference "world" or "world-levelset"), as
/// `distile render --reference world` takes them.
WorldReferenceOptions worldReferenceOptions(const PyRenderArguments& arguments,
                                            const ImageSettings& image) {
    WorldReferenceOptions options;
    options.width = arguments.width.value_or(image.width);
    options.height = arguments.height.value_or(image.height);
    options.outputAovs = arguments.aovs;
    options.method = *arguments.reference == "world-levelset" ? WorldReferenceMethod::LevelSet
                                                              : WorldReferenceMethod::Bvh;
    if (arguments.referenceVoxels) options.levelSet.voxelsPerTexel = *arguments.referenceVoxels;
    return options;
}

/// Refuses a `reference` the command does not take, the keywords of `keywords` a world
/// reference would ignore (kSettingsAWorldReferenceIgnores; None or an empty list asks nothing),
/// and reference_voxels beside any reference but world-levelset or beyond the command's range.
/// The GIL held.
void checkReference(const PyRenderArguments& arguments, const py::dict& keywords) {
    const std::optional<std::string>& reference = arguments.reference;
    if (reference && *reference != "analytic" && *reference != "world" &&
        *reference != "world-levelset") {
        throw InputError("reference: '" + quotedInput(*reference) +
                         "' is not accepted; accepted: True (\"analytic\"), \"world\", "
                         "\"world-levelset\"");
    }
    if (reference == "world" || reference == "world-levelset") {
        for (const char* setting : kSettingsAWorldReferenceIgnores) {
            std::string keyword = setting;
            std::ranges::replace(keyword, '-', '_');
            if (!keywords.contains(keyword)) continue;
            const py::object value = keywords[keyword.c_str()];
            if (value.is_none() || (py::isinstance<py::list>(value) && py::len(value) == 0))
                continue;
            throw InputError(keyword + ": does not apply to reference='" + *reference +
                             "', which " + kWorldReferenceReads + "; leave it out");
        }
    }
    if (!arguments.referenceVoxels) return;
    if (reference != "world-levelset") {
        throw InputError(
            "reference_voxels: applies to reference='world-levelset' only (the voxels of its "
            "level set)");
    }
    const double voxels = *arguments.referenceVoxels;
    if (!(voxels >= 0.25 && voxels <= 16.0)) {
        throw InputError("reference_voxels: " + numberText(voxels) +
                         " is not accepted; it must be in [0.25, 16] world voxels per texel");
    }
}

/// How a render's scene is read: into the tile cache, its warnings and bakes to the callbacks.
using SceneLoad =
    std::function<SceneFile(TileCache&, const SceneWarningCallback&, const BakeProgress&)>;

/// Renders the scene `load` reads (passing its warnings to the callback), as `distile render`
/// does: the render's warnings after the scene's. The pixels report to `progress`
/// (pythonProgress); Ctrl-C ends them, or the bake of a tile of the scene (KeyboardInterrupt).
PyRender renderLoaded(const SceneLoad& load, const py::dict& keywords, const py::object& progress) {
    const PyRenderArguments arguments = renderArguments(keywords);
    checkReference(arguments, keywords);
    const bool world = arguments.reference == "world" || arguments.reference == "world-levelset";
    auto result = std::make_shared<RenderResult>();
    const py::object none = py::none();
    raisingPythonErrors([&] {
        const ProgressCallback report = pythonProgress(progress);
        const ProgressCallback signals = pythonProgress(none);  // the scene's bakes: Ctrl-C only
        py::gil_scoped_release released;
        try {
            TileCache tiles;
            std::vector<std::string> sceneWarnings;
            SceneFile sceneFile = load(
                tiles, [&](const std::string& warning) { sceneWarnings.push_back(warning); },
                [&](const std::string&) { return signals; });
            if (world) {
                const WorldReferenceOptions options =
                    worldReferenceOptions(arguments, sceneFile.image);
                attachTruth(sceneFile);  // analytic detail where there is one, else the tile
                *result = renderWorldReference(sceneFile.scene, options, report).render;
            } else {
                const RenderOptions options = renderOptions(arguments, sceneFile.image);
                if (options.reference) attachTruth(sceneFile);
                *result = renderScene(sceneFile.scene, options, report);
            }
            result->warnings.insert(result->warnings.begin(), sceneWarnings.begin(),
                                    sceneWarnings.end());
        } catch (const InputError& error) {
            throw underRenderKeyword(error);
        }
    });
    return PyRender{result, world};
}

py::dict renderStats(const RenderStats& stats) {
    py::dict out;
    out["rays"] = stats.rays;
    out["base_hits"] = stats.baseHits;
    out["detail_hits"] = stats.detailHits;
    out["march_iterations"] = stats.marchIterations;
    out["mean_iterations"] = stats.meanIterations();
    out["converged"] = stats.converged;
    out["shadow_steps"] = stats.shadowSteps;
    out["shadow_map_samples"] = stats.shadowMapSamples;
    out["shells_tested"] = stats.shellsTested;
    out["shells_traced"] = stats.shellsTraced;
    return out;
}

RenderLayersView layers(const RenderResult& render) {
    if (!render.aovs)
        throw InputError("compare: needs renders made with aovs=True (depth, normal, texel scale)");
    const RenderAovs& aovs = *render.aovs;
    return {render.image, aovs.depth, aovs.normal, aovs.texelScale};
}

/// Each Render's layers in memory; each path's read back from the files `distile render --aovs`
/// writes. The difference image and the hit-error heat map are written where `difference` and
/// `heatMap` say (as `distile compare -o --heatmap`; empty: not written), checked before the
/// comparison, and named in the report.
py::object compareAny(const py::object& a, const py::object& b, const fs::path& difference,
                      const fs::path& heatMap) {
    OutputFiles outputs;
    const auto reserve = [&](const fs::path& image, const std::string& keyword) {
        try {
            requireImageExtension(image);
        } catch (const InputError& error) {
            throw InputError(keyword + ": " + error.what());
        }
        return outputs.add(image, keyword);
    };
    const fs::path differenceTemporary =
        difference.empty() ? fs::path() : reserve(difference, "compare: difference");
    const fs::path heatMapTemporary =
        heatMap.empty() ? fs::path() : reserve(heatMap, "compare: heatmap");
    auto compareViews = [&](const RenderLayersView& viewA, const RenderLayersView& viewB) {
        RenderComparison comparison;
        {
            py::gil_scoped_release released;
            Image differenceImage, heatMapImage;
            comparison = compareRenders(viewA, viewB, &differenceImage, &heatMapImage);
            if (!difference.empty()) writeImage(differenceImage, differenceTemporary);
            if (!heatMap.empty()) writeImage(heatMapImage, heatMapTemporary);
            outputs.commit();
        }
        nlohmann::json report = renderComparisonJson(comparison);
        if (!difference.empty()) report["difference"] = difference.string();
        if (!heatMap.empty()) report["heatmap"] = heatMap.string();
        return jsonValue(reportText(report));
    };
    std::optional<RenderFiles> filesA, filesB;
    auto view = [](const py::object& render, std::optional<RenderFiles>& files,
                   const std::string& role) -> RenderLayersView {
        if (py::isinstance<PyRender>(render)) return layers(renderOf(render));
        if (!py::isinstance<py::str>(render) && !py::hasattr(render, "__fspath__")) {
            const std::string keyword = role == "A" ? "a" : "b";
            throw py::type_error(
                "compare: " + keyword +
                " must be a distile.Render or the path (str or os.PathLike) of "
                "an image `distile render --aovs` wrote; got " +
                py::str(py::type::of(render).attr("__name__")).cast<std::string>());
        }
        files.emplace(readRenderFiles(render.cast<fs::path>(), role));
        return files->view();
    };
    const RenderLayersView viewA = view(a, filesA, "A");
    const RenderLayersView viewB = view(b, filesB, "B");
    return compareViews(viewA, viewB);
}

}  // namespace

}  // namespace distile::python

PYBIND11_MODULE(_distile, module) {
    using namespace distile;
    using namespace distile::python;
    module.doc() = "distile's compiled core; use the package `distile`";
    // Bad input: ValueError subclasses; their text is the command's message without the
    // "distile: error: " prefix.
    static py::exception<InputError> inputError(module, "InputError", PyExc_ValueError);
    static py::exception<FormatError> formatError(module, "FormatError", PyExc_ValueError);
    static py::exception<InternalError> internalError(module, "InternalError", PyExc_RuntimeError);
    py::register_exception_translator([](std::exception_ptr thrown) {
        // A message quotes file names, which on Linux may be any bytes: those that are not UTF-8
        // are shown escaped (PyErr_SetString's strict decoding left the message empty).
        const auto raise = [](PyObject* type, const char* message) {
            PyObject* text =
                PyUnicode_DecodeUTF8(message, Py_ssize_t(std::strlen(message)), "backslashreplace");
            if (!text) {
                PyErr_Clear();
                PyErr_SetString(type, "(a message that is not text)");
                return;
            }
            PyErr_SetObject(type, text);
            Py_DECREF(text);
        };
        try {
            if (thrown) std::rethrow_exception(thrown);
        } catch (const InputError& error) {
            raise(inputError.ptr(), error.what());
        } catch (const FormatError& error) {
            raise(formatError.ptr(), error.what());
        } catch (const InternalError& error) {
            raise(internalError.ptr(), error.what());
        } catch (const std::system_error& error) {
            raise(PyExc_OSError, error.what());
        }
    });

    py::class_<PyTile>(module, "Tile", "A distance tile (signed distances in texels)")
        .def_property_readonly(
            "size",
            [](py::handle self) {
                const Size3& size = tileOf(self).size();
                return py::make_tuple(size.width, size.height, size.depth);
            },
            "(W, H, D) in texels")
        .def_property_readonly(
            "array",
            [](py::object self) {
                const Tile& tile = tileOf(self);
                const Size3& size = tile.size();
                return readOnlyView(tile.distancesTexels().data(),
                                    {size.depth, size.height, size.width}, self);
            },
            "The distances as a read-only (D, H, W) float32 view (no copy): array[z, y, x] is "
            "texel (x, y, z), centred at (x + 0.5, y + 0.5, z + 0.5); negative inside")
        .def_property_readonly(
            "metadata",
            [](py::handle self) {
                const Tile& tile = tileOf(self);
                const TileProvenance& provenance = tile.provenance;
                py::dict out;
                out["size"] = toString(tile.size());
                out["units"] = "texels";
                out["source"] = provenance.source;
                out["params"] = provenance.params.empty() ? py::object(py::dict())
                                                          : jsonValue(provenance.params);
                out["band_texels"] = provenance.halfBandTexels;
                out["hash"] = hexDigits(tileHash(tile));
                if (!provenance.sourceFile.empty()) {
                    out["source_file"] = provenance.sourceFile.string();
                    out["source_hash"] = provenance.sourceHash;
                }
                if (!provenance.check.empty()) out["check"] = provenance.check;
                return out;
            },
            "What the tile file's distile: attributes say, without the prefix "
            "(docs/tile_format.md)")
        .def(
            "save",
            [](py::handle self, const fs::path& file, bool half) {
                const Tile& tile = tileOf(self);
                py::gil_scoped_release released;
                writeTileExr(tile, file, half ? TileStorage::Half16 : TileStorage::Float32);
            },
            py::arg("file"), py::arg("half") = false,
            "Write the tile as an EXR atlas (as `distile bake -o`, `--half` with half=True)")
        .def(
            "save_png",
            [](py::handle self, const fs::path& file, int bits, bool keepSign) {
                const Tile& tile = tileOf(self);
                py::gil_scoped_release released;
                if (!keepSign) return writeTilePng(tile, file, bits);
                if (bits != 16)
                    throw InputError(
                        "save_png: signed: the atlas that keeps the sign is 16-bit "
                        "(bits=16), not " +
                        std::to_string(bits) + "-bit");
                writeSignedTilePng(tile, file);
            },
            py::arg("file"), py::arg("bits") = 16, py::arg("signed") = false,
            "Write the 8- or 16-bit PNG atlas (as `distile bake --png8/--png16`; signed=True: "
            "--png16-signed, 0.5 + distance / 2R)")
        .def(
            "save_preview",
            [](py::handle self, const fs::path& file) {
                const Tile& tile = tileOf(self);
                bool labelled = true;
                {
                    py::gil_scoped_release released;
                    requireExtension(file, "save_preview", ".png", "the contact sheet is a PNG");
                    labelled = writeTilePreview(tile, file);
                }
                if (!labelled)
                    warnPython(
                        "save_preview: the labels were left out: no DejaVu Sans font "
                        "(Debian: fonts-dejavu-core)");
            },
            py::arg("file"),
            "Draw the tile's slices as a contact sheet (as `distile preview -o`, .png)")
        .def(
            "save_view",
            [](py::handle self, const fs::path& file, const std::string& object,
               std::optional<std::array<float, 2>> uvScale, std::optional<float> depth,
               std::optional<std::array<float, 2>> sphereUvScale, std::optional<float> sphereDepth,
               bool openFloor, const std::string& title) {
                const Tile& tile = tileOf(self);
                TilePageView view;
                view.object = object;
                if (uvScale) view.uvScale = {(*uvScale)[0], (*uvScale)[1]};
                if (depth) view.depthWorld = *depth;
                if (sphereUvScale) view.sphereUvScale = {(*sphereUvScale)[0], (*sphereUvScale)[1]};
                if (sphereDepth) view.sphereDepthWorld = *sphereDepth;
                view.solidFloor = !openFloor;
                py::gil_scoped_release released;
                requireExtension(file, "save_view", ".html", "the page is HTML");
                try {
                    writeTilePage(tile, title, view, file);
                } catch (const InputError& error) {
                    throw shownUnder(error, {{"uvScale.x", "uv_scale"},
                                             {"uvScale.y", "uv_scale"},
                                             {"depthWorld", "depth"},
                                             {"sphereUvScale.x", "sphere_uv_scale"},
                                             {"sphereUvScale.y", "sphere_uv_scale"},
                                             {"sphereDepthWorld", "sphere_depth"}});
                }
            },
            py::arg("file"), py::kw_only(), py::arg("object") = "plane",
            py::arg("uv_scale") = py::none(), py::arg("depth") = py::none(),
            py::arg("sphere_uv_scale") = py::none(), py::arg("sphere_depth") = py::none(),
            py::arg("open_floor") = false, py::arg("title") = "tile",
            "Write the web page that draws the tile with the reference shader (as `distile "
            "view -o`, .html): object \"plane\" or \"sphere\", uv_scale=(u, v), depth, "
            "sphere_uv_scale, sphere_depth, open_floor, title");

    module.def(
        "load_tile",
        [](const fs::path& file) {
            py::gil_scoped_release released;
            return PyTile{std::make_shared<const Tile>(readTileExr(file))};
        },
        py::arg("file"), "Read a tile file (.exr) written by distile");
    module.def("bake_recipe", &bakeRecipe, py::arg("recipe_json"), py::arg("name"),
               py::arg("progress") = py::none());
    module.def("bake_recipe_with_level_set", &bakeRecipeWithLevelSet, py::arg("recipe_json"),
               py::arg("name"), py::arg("vdb"), py::arg("repeat_x"), py::arg("repeat_y"),
               py::arg("progress") = py::none());

    py::class_<PyRender>(module, "Render", "A rendered image with its statistics and AOVs")
        .def_property_readonly(
            "image", [](py::object self) { return imageView(renderOf(self).image, self); },
            "Linear RGB as a read-only (height, width, 3) float32 view, row 0 at the top")
        .def_property_readonly(
            "aovs",
            [](py::object self) {
                const PyRender& held = pyRenderOf(self);
                const RenderResult& render = *held.result;
                py::dict out;
                if (!render.aovs) return out;
                for (const AovFile& aov : kAovFiles) {
                    if (holdsAov(aovNames(held), aov.name))
                        out[aov.name] = imageView((*render.aovs).*aov.layer, self);
                }
                return out;
            },
            "The AOVs by name (depth, normal, ...), each a (height, width, 3) view; empty "
            "without aovs=True (a world reference's: depth, normal, texel_scale)")
        .def_property_readonly(
            "stats", [](py::handle self) { return renderStats(renderOf(self).stats); },
            "Counters as distile render prints them: rays, base_hits (rays that hit a surface), "
            "detail_hits (of those, on a tile), converged (of detail_hits, within the budget), "
            "march_iterations, mean_iterations, shadow_steps, shadow_map_samples, shells_tested, "
            "shells_traced")
        .def_property_readonly(
            "warnings", [](py::handle self) { return renderOf(self).warnings; },
            "What distile render prints as warnings (render() also gives each as a UserWarning)")
        .def(
            "save",
            [](py::handle self, const fs::path& file) {
                const PyRender& held = pyRenderOf(self);
                py::gil_scoped_release released;
                writeRenderFiles(*held.result, file, aovNames(held));
            },
            py::arg("file"),
            "Write the image (.png, .exr, .tif) and, with AOVs, each beside it as `distile "
            "render --aovs` does");
    module.def(
        "render_scene_file",
        [](const fs::path& file, const py::dict& arguments, const py::object& progress) {
            return renderLoaded(
                [&](TileCache& tiles, const SceneWarningCallback& warn,
                    const BakeProgress& bakeProgress) {
                    return loadSceneFile(file, tiles, warn, bakeProgress);
                },
                arguments, progress);
        },
        py::arg("file"), py::arg("arguments"), py::arg("progress") = py::none());
    module.def(
        "render_scene_json",
        [](const std::string& sceneJson, const fs::path& folder, const std::string& name,
           const py::dict& arguments, const py::object& progress) {
            return renderLoaded(
                [&](TileCache& tiles, const SceneWarningCallback& warn,
                    const BakeProgress& bakeProgress) {
                    return loadSceneJson(sceneJson, folder, name, tiles, warn, bakeProgress);
                },
                arguments, progress);
        },
        py::arg("scene_json"), py::arg("folder"), py::arg("name"), py::arg("arguments"),
        py::arg("progress") = py::none());
    module.def("compare", &compareAny, py::arg("a"), py::arg("b"),
               py::arg("difference") = fs::path(), py::arg("heatmap") = fs::path());

    module.def(
        "check_tile",
        [](py::handle tile, const std::string& tileName, const fs::path& tileFile,
           const py::dict& keywords, const fs::path& plot) {
            const Tile& checked = tileOf(tile);
            const TileCheckOptions options = checkOptions(keywords);
            TileCheck check;
            std::vector<std::string> warnings;
            try {
                py::gil_scoped_release released;
                // The plot (as `distile check --plot`) is checked before the check and written
                // after it.
                OutputFiles outputs;
                fs::path plotTemporary;
                if (!plot.empty()) {
                    requireExtension(plot, "check: plot", ".png", "the plot is a PNG");
                    plotTemporary = outputs.add(plot, "check: plot");
                }
                check = checkTile(checked, tileName, tileFile, options);
                if (!plot.empty()) {
                    if (!writeTileErrorPlot(checked, check.truth, check.bandTexels, plotTemporary))
                        warnings.push_back(
                            "check: plot: the labels were left out: no DejaVu Sans font (Debian: "
                            "fonts-dejavu-core)");
                    outputs.commit();
                }
            } catch (const InputError& error) {
                // Under check()'s keywords, not the C++ members.
                throw shownUnder(error, {{"maxOverestimateTexels", "max_overestimate"},
                                         {"maxOverestimateShare", "max_overestimate_share"},
                                         {"maxRmsTexels", "max_rms"},
                                         {"maxTracerOverestimateTexels", "max_tracer_overestimate"},
                                         {"maxNearErrorTexels", "max_near_error"},
                                         {"meshScale", "scale"},
                                         {"meshOffsetTexels", "offset"}});
            }
            nlohmann::json report = tileCheckJson(check, options, tileName);
            if (!plot.empty()) report["plot"] = plot.string();
            return py::make_tuple(jsonValue(reportText(report)), warnings);
        },
        py::arg("tile"), py::arg("tile_name"), py::arg("tile_file"), py::arg("options"),
        py::arg("plot") = fs::path());

    // Tiles and renders come from the module's functions only. Python's default __new__ would
    // make an instance no constructor filled, whose accessors read freed or unwritten memory (a
    // segfault); the module's own results are made without __new__.
    for (const char* name : {"Tile", "Render"}) {
        const std::string message = std::string("distile.") + name +
                                    " objects come from the module's functions (load_tile, "
                                    "bake_*, render); they cannot be made empty";
        module.attr(name).attr("__new__") =
            py::cpp_function([message](const py::args&, const py::kwargs&) -> py::object {
                throw py::type_error(message);
            });
    }

    // tbb::global_control limits every TBB arena of the process while it lives.
    module.def(
        "set_threads",
        [](int threads) {
            static std::unique_ptr<tbb::global_control> limit;
            if (threads < 0 || threads > 1024)
                throw InputError::inField("threads", std::to_string(threads) +
                                                         " is not accepted; give 1 to 1024, or 0 "
                                                         "for all cores");
            limit.reset();
            if (threads > 0)
                limit = std::make_unique<tbb::global_control>(
                    tbb::global_control::max_allowed_parallelism, std::size_t(threads));
        },
        py::arg("threads"));
}
