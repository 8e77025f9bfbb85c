// distile compare: how far one render is from another (usually the reference) of the same scene.
#include <cmath>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "check/reports.h"
#include "cli/app.h"
#include "cli/arguments.h"
#include "cli/commands.h"
#include "common/atomic_file.h"
#include "common/error.h"
#include "render/compare.h"
#include "render/image.h"
#include "render/render_files.h"

namespace distile::cli {

namespace fs = std::filesystem;

namespace {

struct CompareArguments {
    fs::path a;
    fs::path b;
    fs::path difference;
    fs::path heatMap;
    bool json = false;
};

void printClass(const char* name, const HitErrorSummary& summary) {
    std::printf("  %-10s %9llu %9llu", name, static_cast<unsigned long long>(summary.pixels),
                static_cast<unsigned long long>(summary.hitErrorSamples));
    if (summary.hitErrorSamples == 0) {  // no pixel to measure in texels: no figure, not 0
        std::printf(" %10s %10s %12s %10.3f\n", "n/a", "n/a", "n/a", summary.meanNormalErrorDeg);
        return;
    }
    std::printf(" %10.4f %10.4f %12.4f %10.3f\n", summary.meanHitErrorTexels,
                summary.p99HitErrorTexels, summary.maxHitErrorTexels, summary.meanNormalErrorDeg);
}

void runCompare(const CompareArguments& arguments) {
    const fs::path differencePath =
        arguments.difference.empty() ? aovPath(arguments.a, "diff", ".png") : arguments.difference;
    const fs::path heatMapPath =
        arguments.heatMap.empty() ? aovPath(arguments.a, "hit_error", ".png") : arguments.heatMap;
    requireOutput(differencePath, "-o", {".png", ".exr", ".tif", ".tiff"});
    requireOutput(heatMapPath, "--heatmap", {".png", ".exr", ".tif", ".tiff"});
    OutputFiles outputs;  // checked now, written together after the comparison
    const fs::path differenceTemporary = outputs.add(differencePath, "-o");
    const fs::path heatMapTemporary = outputs.add(heatMapPath, "--heatmap");
    const RenderFiles a = readRenderFiles(arguments.a, "A");
    const RenderFiles b = readRenderFiles(arguments.b, "B");
    if (a.image.width != b.image.width || a.image.height != b.image.height) {
        throw InputError("compare: A (" + arguments.a.string() + ") is " +
                         std::to_string(a.image.width) + "x" + std::to_string(a.image.height) +
                         " but B (" + arguments.b.string() + ") is " +
                         std::to_string(b.image.width) + "x" + std::to_string(b.image.height) +
                         "; only renders of the same size can be compared");
    }
    Image difference, heatMap;
    const RenderComparison c = compareRenders(a.view(), b.view(), &difference, &heatMap);
    writeImage(difference, differenceTemporary);
    writeImage(heatMap, heatMapTemporary);
    outputs.commit();
    if (arguments.json) {
        nlohmann::json out = renderComparisonJson(c);
        out["a"] = arguments.a.string();
        out["b"] = arguments.b.string();
        out["difference"] = differencePath.string();
        out["heatmap"] = heatMapPath.string();
        std::printf("%s\n", reportText(out).c_str());
        return;
    }
    std::printf("compared %s with %s (%dx%d)\n", arguments.a.c_str(), arguments.b.c_str(), c.width,
                c.height);
    std::printf(
        "pixels: %llu; both hit: %llu (interior %llu, silhouette %llu); coverage "
        "mismatches: %llu (%.4f%% of all)\n",
        static_cast<unsigned long long>(c.pixels), static_cast<unsigned long long>(c.bothHit),
        static_cast<unsigned long long>(c.interior.pixels),
        static_cast<unsigned long long>(c.silhouette.pixels),
        static_cast<unsigned long long>(c.coverageMismatches), 100.0 * c.coverageMismatchShare);
    if (c.interior.hitErrorSamples == 0) {
        std::printf(
            "mean hit error (interior pixels): n/a (no interior pixel where either render has a "
            "texel scale: a tile hit of a render made with --aovs, not a world reference)\n");
    } else {
        std::printf("mean hit error (interior pixels): %.4f texels, p99 %.4f, max %.4f\n",
                    c.interior.meanHitErrorTexels, c.interior.p99HitErrorTexels,
                    c.interior.maxHitErrorTexels);
    }
    std::printf("by class (hit error in texels, normal angle error in degrees):\n");
    std::printf("  %-10s %9s %9s %10s %10s %12s %10s\n", "class", "pixels", "samples", "mean",
                "p99", "max", "normal");
    printClass("interior", c.interior);
    printClass("silhouette", c.silhouette);
    printClass("all", {c.bothHit, c.hitErrorSamples, c.meanHitErrorTexels, c.p99HitErrorTexels,
                       c.maxHitErrorTexels, c.meanNormalErrorDeg});
    std::printf("%s\n", kSilhouetteRule);
    std::printf("PSNR (sRGB-encoded [0, 1], 8-bit for PNGs): %.2f dB\n", c.psnrDb);
    std::printf("difference image written to %s\n", fs::absolute(differencePath).c_str());
    std::printf("hit-error heat map (log scale, 0.01 to 100 texels) written to %s\n",
                fs::absolute(heatMapPath).c_str());
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
                        "Difference heat map of the shaded images to write (default: beside A as "
                        "<A's stem>.diff.png)");
    command->add_option(
        "--heatmap", arguments->heatMap,
        "Hit-error heat map to write (default: beside A as <A's stem>.hit_error.png)"
        ": each pixel where both hit coloured by its hit error on a log scale from "
        "0.01 texel (blue) through 1 (green) to 100 texels (red), magenta where "
        "one render hits and the other misses, dark grey where both miss, mid grey "
        "where no texel scale is known; a colour bar with labels in texels below");
    command->add_flag("--json", arguments->json, "Print the figures as one JSON object");
    command->footer(
        "Figures: hit error (|depth A - depth B| along the ray, in texels by A's texel scale, "
        "else B's), coverage mismatches (one render hits, the other misses), mean normal angle "
        "error and PSNR of the shaded images. The pixels where both hit are split in two "
        "classes, reported apart and together (all): silhouette pixels, where in either render "
        "one of the pixel's 8 neighbours misses or lies across a depth jump (a step between the "
        "two depths, in texels by the pixel's texel scale, over 1 texel and over twice each "
        "step beside it on the same line of pixels that goes the same way: a pixel alone "
        "through a gap is one), and interior pixels, the others. One pixel "
        "that hits a far surface behind a silhouette can outweigh all the others in a mean; the "
        "headline mean and p99 are the interior ones. On detail the image does not resolve "
        "(several texels per pixel) most pixels are silhouette pixels.\n\n" +
        std::string(kExitStatusHelp));
    command->callback([arguments] { runCompare(*arguments); });
}

}  // namespace distile::cli
