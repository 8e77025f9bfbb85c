// distile compare: how far one render is from another (usually the reference) of the same scene.
#include <cmath>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>

#include "cli/arguments.h"
#include "cli/commands.h"
#include "common/error.h"
#include "render/compare.h"
#include "render/image.h"

namespace distile::cli {

namespace fs = std::filesystem;

namespace {

struct CompareArguments {
    fs::path a;
    fs::path b;
    fs::path difference;
    bool json = false;
};

/// A render read back from its files: the image and the AOVs written beside it by render --aovs.
struct RenderFiles {
    Image image, depth, normal, texelScale;
    RenderLayersView view() const { return {image, depth, normal, texelScale}; }
};

fs::path besidePath(const fs::path& image, const std::string& name, const std::string& extension) {
    return image.parent_path() / (image.stem().string() + "." + name + extension);
}

Image readLayer(const fs::path& file, const std::string& role) {
    if (!fs::exists(file)) {
        throw InputError(role + ": " + file.string() +
                         " does not exist; compare needs renders written with --aovs");
    }
    return readImage(file);
}

RenderFiles readRender(const fs::path& image, const std::string& role) {
    if (!fs::exists(image))
        throw InputError(role + ": image " + image.string() + " does not exist");
    return {readImage(image), readLayer(besidePath(image, "depth", ".exr"), role),
            readLayer(besidePath(image, "normal", ".png"), role),
            readLayer(besidePath(image, "texel_scale", ".exr"), role)};
}

void runCompare(const CompareArguments& arguments) {
    const fs::path differencePath = arguments.difference.empty()
                                        ? besidePath(arguments.a, "diff", ".png")
                                        : arguments.difference;
    requireOutput(differencePath, "-o", {".png", ".exr", ".tif", ".tiff"});
    const RenderFiles a = readRender(arguments.a, "A");
    const RenderFiles b = readRender(arguments.b, "B");
    Image difference;
    const RenderComparison c = compareRenders(a.view(), b.view(), &difference);
    writeImage(difference, differencePath);
    if (arguments.json) {
        // JSON has no infinity: identical images give "psnr_db": null.
        const nlohmann::json psnr =
            std::isfinite(c.psnrDb) ? nlohmann::json(c.psnrDb) : nlohmann::json(nullptr);
        const nlohmann::json out = {
            {"a", arguments.a.string()},
            {"b", arguments.b.string()},
            {"width", c.width},
            {"height", c.height},
            {"pixels", c.pixels},
            {"both_hit", c.bothHit},
            {"coverage_mismatches", c.coverageMismatches},
            {"coverage_mismatch_share", c.coverageMismatchShare},
            {"hit_error_samples", c.hitErrorSamples},
            {"hit_error_units", "texels"},
            {"hit_error_mean", c.meanHitErrorTexels},
            {"hit_error_p99", c.p99HitErrorTexels},
            {"hit_error_max", c.maxHitErrorTexels},
            {"normal_error_mean_deg", c.meanNormalErrorDeg},
            {"psnr_db", psnr},
            {"psnr_of", "sRGB-encoded values in [0, 1], peak 1 (8-bit PSNR for PNGs)"},
            {"difference", differencePath.string()}};
        std::printf("%s\n", out.dump().c_str());
        return;
    }
    std::printf("compared %s with %s (%dx%d)\n", arguments.a.c_str(), arguments.b.c_str(), c.width,
                c.height);
    std::printf("hit error (texels, %llu pixels where both hit): mean %.4f, p99 %.4f, max %.4f\n",
                static_cast<unsigned long long>(c.hitErrorSamples), c.meanHitErrorTexels,
                c.p99HitErrorTexels, c.maxHitErrorTexels);
    std::printf("coverage mismatch: %llu pixels, %.4f%% of all\n",
                static_cast<unsigned long long>(c.coverageMismatches),
                100.0 * c.coverageMismatchShare);
    std::printf("normal angle error: mean %.3f deg\n", c.meanNormalErrorDeg);
    std::printf("PSNR (sRGB-encoded [0, 1], 8-bit for PNGs): %.2f dB\n", c.psnrDb);
    std::printf("difference image written to %s\n", fs::absolute(differencePath).c_str());
}

}  // namespace

void addCompareCommand(CLI::App& app) {
    auto arguments = std::make_shared<CompareArguments>();
    CLI::App* command = app.add_subcommand("compare",
                                           "Compare two renders of the same scene written with "
                                           "--aovs (A against B, usually the reference)");
    command
        ->add_option("a", arguments->a,
                     "Render to measure (its .depth.exr, .normal.png, .texel_scale.exr beside it)")
        ->required();
    command
        ->add_option("b", arguments->b, "Render to measure against, e.g. from render --reference")
        ->required();
    command->add_option("-o,--output", arguments->difference,
                        "Difference heat map to write (default: beside A as <A's stem>.diff.png)");
    command->add_flag("--json", arguments->json, "Print the figures as one JSON object");
    command->callback([arguments] { runCompare(*arguments); });
}

}  // namespace distile::cli
