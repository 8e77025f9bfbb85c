// Pictures of a tile: the reference shader's page in headless Chromium against the CPU renderer,
// the contact sheet's colours, contour and colour bar, and the commands' refusals.
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <glm/geometric.hpp>
#include <vector>

#include "cli_fixture.h"
#include "sampler/tile.h"
#include "sampler/tile_io.h"
#include "view/contact_sheet.h"
#include "view/tile_page.h"

namespace distile {
namespace {

/// Pixels of an 8-bit image as read, no colour conversion: channels() values per pixel.
struct Pixels {
    int width = 0, height = 0, channels = 0;
    std::vector<std::uint8_t> values;
    const std::uint8_t* at(int x, int y) const {
        return &values[(std::size_t(y) * std::size_t(width) + std::size_t(x)) * channels];
    }
};

Pixels readPixels8(const fs::path& file) {
    auto input = OIIO::ImageInput::open(file.string());
    if (!input) throw std::runtime_error("cannot open " + file.string());
    const OIIO::ImageSpec& spec = input->spec();
    Pixels pixels{spec.width, spec.height, spec.nchannels, {}};
    pixels.values.resize(std::size_t(spec.width) * spec.height * spec.nchannels);
    if (!input->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::UINT8, pixels.values.data()))
        throw std::runtime_error("cannot read " + file.string());
    return pixels;
}

/// First channel of a float image (an AOV), row 0 at the top.
std::vector<float> readChannel0(const fs::path& file, int& width, int& height) {
    auto input = OIIO::ImageInput::open(file.string());
    if (!input) throw std::runtime_error("cannot open " + file.string());
    width = input->spec().width;
    height = input->spec().height;
    std::vector<float> values(std::size_t(width) * height);
    if (!input->read_image(0, 0, 0, 1, OIIO::TypeDesc::FLOAT, values.data()))
        throw std::runtime_error("cannot read " + file.string());
    return values;
}

/// Headless Chromium, or empty when it is not installed (DISTILE_CHROMIUM overrides the path).
fs::path chromium() {
    const char* chosen = std::getenv("DISTILE_CHROMIUM");
    const fs::path program = chosen ? fs::path(chosen) : fs::path("/usr/bin/chromium");
    return fs::exists(program) ? program : fs::path();
}

using ViewCommand = Cli;

// The page's shader draws the flat chain-mail sheet with the hit depth in 24 bits per pixel;
// the CPU renderer draws the same view (data/scenes/sheet.json's plane, uv scale and depth) with
// its depth AOV. Both march the same tile the same way, so they agree up to the half-float
// storage of the page's tile (relative 2^-11, 0.004 texel at the 7-texel largest distance)
// against the renderer's 16-bit codes (the signed PNG's codes: steps of 2 x 7.2 / 65535 texel),
// float rounding on two machines, and the ray's pixel centre. A ray whose march ends within epsilon
// (0.02 texel) of the surface ends within 0.02 / cos(angle to the normal) along it; where the
// rounding tips one comparison of the march (a sample just below or above epsilon, a step landing
// inside or not), the two part by up to a step of the budgeted march (about a texel at grazing
// angles). So: 99 % of the pixels that both hit lie within 0.1 texel along the ray, and at most 0.5
// % of pixels are hit in one picture and missed in the other (the plane's edge against the sky, a
// pixel wide).
TEST_F(ViewCommand, ShaderPageAgreesWithTheCpuRenderInChromium) {
    const fs::path browser = chromium();
    if (browser.empty()) GTEST_SKIP() << "chromium is not installed (Debian: chromium)";
    constexpr int kWidth = 320, kHeight = 256;
    ASSERT_EQ(run({"bake", "chainmail", "-o", "tile.exr"}).status, 0);
    writeText(path("sheet.json"), R"({
      "camera": {"eye": [0.0, -2.1, 1.47], "target": [0.0, 0.0, 0.0], "up": [0, 0, 1], "fov_deg": 40},
      "lights": [{"direction": [-0.4, 0.3, -1.0]}],
      "objects": [{"mesh": "plane", "transform": {"scale": 2.0},
                   "material": {"tile": "tile.exr", "uv_scale": [4, 4], "depth": 0.0625}}]})");
    const RunResult render =
        run({"render", "sheet.json", "-o", "cpu.png", "--width", std::to_string(kWidth), "--height",
             std::to_string(kHeight), "--no-shadows", "--aovs"});
    ASSERT_EQ(render.status, 0) << render.err;
    const RunResult view = run({"view", "tile.exr", "-o", "tile.html"});
    ASSERT_EQ(view.status, 0) << view.err;

    int width = 0, height = 0;
    const std::vector<float> cpuDepth = readChannel0(path("cpu.depth.exr"), width, height);
    const std::vector<float> texelScale = readChannel0(path("cpu.texel_scale.exr"), width, height);
    ASSERT_EQ(width, kWidth);
    ASSERT_EQ(height, kHeight);
    // The tile as half floats (the EXR's), then as the signed 16-bit PNG atlas's codes.
    for (const std::string texture : {"half", "png16-signed"}) {
        SCOPED_TRACE("texture=" + texture);
        const std::string url = "file://" + path("tile.html").string() +
                                "?object=plane&eye=0,-2.1,1.47&target=0,0,0&up=0,0,1&fov=40"
                                "&plane_size=4&uv_scale=4,4&depth=0.0625&output=depth"
                                "&depth_range=16&texture=" +
                                texture;
        // SwiftShader: Chromium's software WebGL2, the same on every machine.
        const std::string flags =
            " --headless=new --no-sandbox --use-angle=swiftshader --enable-unsafe-swiftshader"
            " --hide-scrollbars --force-device-scale-factor=1 --user-data-dir=" +
            shellQuote(path("profile").string()) + " --window-size=" + std::to_string(kWidth) +
            "," + std::to_string(kHeight);
        const fs::path shot = path("gpu_" + texture + ".png");
        const std::string screenshot = "timeout 60 " + shellQuote(browser.string()) + flags +
                                       " --screenshot=" + shellQuote(shot.string()) + " " +
                                       shellQuote(url) + " >/dev/null 2>" +
                                       shellQuote(path("chromium.log").string());
        ASSERT_EQ(std::system(screenshot.c_str()), 0) << readText(path("chromium.log"));
        ASSERT_TRUE(fs::exists(shot)) << readText(path("chromium.log"));

        const Pixels gpu = readPixels8(shot);
        ASSERT_EQ(gpu.width, kWidth);
        ASSERT_EQ(gpu.height, kHeight);
        int bothHit = 0, coverageMismatch = 0, within = 0, withinHundredth = 0, gpuHits = 0;
        double sumTexels = 0.0;
        for (int y = 0; y < kHeight; ++y) {
            for (int x = 0; x < kWidth; ++x) {
                const std::uint8_t* rgb = gpu.at(x, y);
                const double code = double(rgb[0]) * 65536.0 + double(rgb[1]) * 256.0 + rgb[2];
                const double gpuDepth = code / 16777215.0 * 16.0;
                const std::size_t index = std::size_t(y) * kWidth + x;
                const bool gpuHit = code > 0.0, cpuHit = cpuDepth[index] > 0.0f;
                gpuHits += gpuHit;
                if (gpuHit != cpuHit) ++coverageMismatch;
                if (!gpuHit || !cpuHit) continue;
                ++bothHit;
                const double texels = std::abs(gpuDepth - cpuDepth[index]) * texelScale[index];
                sumTexels += texels;
                within += texels <= 0.1;
                withinHundredth += texels <= 0.01;
            }
        }
        if (gpuHits == 0) {
            // Nothing drawn: the page says why in its body's data-status.
            const std::string dump = "timeout 60 " + shellQuote(browser.string()) + flags +
                                     " --dump-dom " + shellQuote(url) + " 2>/dev/null";
            FILE* pipe = popen(dump.c_str(), "r");
            std::string dom;
            for (char buffer[4096]; pipe && std::fgets(buffer, sizeof buffer, pipe);) dom += buffer;
            if (pipe) pclose(pipe);
            const std::size_t at = dom.find("data-status");
            FAIL() << "the page drew nothing in Chromium: "
                   << (at == std::string::npos ? dom.substr(0, 400) : dom.substr(at, 400));
        }
        const double pixels = double(kWidth) * kHeight;
        std::printf(
            "shader (%s) vs CPU depth: %d pixels both hit, %.4f %% coverage mismatch, "
            "%.3f %% within 0.1 texel, %.3f %% within 0.01 texel, mean |difference| "
            "%.4f texel\n",
            texture.c_str(), bothHit, 100.0 * coverageMismatch / pixels, 100.0 * within / bothHit,
            100.0 * withinHundredth / bothHit, sumTexels / bothHit);
        EXPECT_GT(bothHit, int(0.7 * pixels));  // the sheet fills the lower 80 % of the view
        EXPECT_LE(coverageMismatch, 0.005 * pixels);
        EXPECT_GE(within, 0.99 * bothHit);
    }
}

TEST_F(ViewCommand, ATileLargerThanTheGpusTexturesSaysSoInThePage) {
    // 2100 texels along y: past the 2048 a side that Chromium's SwiftShader (and most GPUs) take
    // in a 3D texture. distile warns; the page says why it draws nothing instead of a WebGL
    // error number.
    const fs::path browser = chromium();
    if (browser.empty()) GTEST_SKIP() << "chromium is not installed (Debian: chromium)";
    ASSERT_EQ(run({"bake", "grating", "--size", "8x2100x8", "--bars", "1", "--bar-width", "2",
                   "--bar-height", "2", "--edge-radius", "0.5", "-o", "tall.exr"})
                  .status,
              0);
    const RunResult view = run({"view", "tall.exr", "-o", "tall.html"});
    ASSERT_EQ(view.status, 0) << view.err;
    EXPECT_NE(view.err.find("the tile is 8x2100x8 texels"), std::string::npos) << view.err;
    const std::string dump =
        "timeout 60 " + shellQuote(browser.string()) +
        " --headless=new --no-sandbox --use-angle=swiftshader --enable-unsafe-swiftshader"
        " --virtual-time-budget=5000 --user-data-dir=" +
        shellQuote(path("profile").string()) + " --dump-dom " +
        shellQuote("file://" + path("tall.html").string()) + " 2>/dev/null";
    FILE* pipe = popen(dump.c_str(), "r");
    std::string dom;
    for (char buffer[4096]; pipe && std::fgets(buffer, sizeof buffer, pipe);) dom += buffer;
    if (pipe) pclose(pipe);
    EXPECT_NE(dom.find("data-status=\"error: the tile is 8x2100x8 texels; this GPU's 3D textures "
                       "take at most"),
              std::string::npos)
        << dom.substr(0, 400);
}

/// Pixel (x, y) of an 8-bit RGB picture as colour components in [0, 1].
glm::vec3 colorAt(const Pixels& pixels, int x, int y) {
    const std::uint8_t* rgb = pixels.at(x, y);
    return glm::vec3(rgb[0], rgb[1], rgb[2]) / 255.0f;
}

void expectColor(const glm::vec3& actual, const glm::vec3& expected, const char* what) {
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(actual[c], expected[c], 0.5f / 255.0f + 1e-6f) << what;
}

/// A 32 x 16 x 2 field: a ball of radius 5 texels at (10.5, 4.5, 1) (exact distances, texel
/// centres), so the inside, the outside and the sign change sit at known texels.
Tile ballTile() {
    Tile tile({32, 16, 2});
    for (int z = 0; z < 2; ++z)
        for (int y = 0; y < 16; ++y)
            for (int x = 0; x < 32; ++x)
                tile.at(x, y, z) =
                    std::hypot(float(x) - 10.0f, float(y) - 4.0f, float(z) - 0.5f) - 5.0f;
    return tile;
}

TEST(ContactSheet, InsideIsBlueOutsideRedContourBlackAndYIsUp) {
    const fs::path file =
        fs::temp_directory_path() / ("distile_sheet_" + std::to_string(::getpid()) + ".png");
    const Tile tile = ballTile();
    writeTilePreview(tile, file);
    const Pixels sheet = readPixels8(file);
    fs::remove(file);
    const ContactSheetLayout layout(tile.size());
    ASSERT_EQ(sheet.width, layout.width);
    ASSERT_EQ(sheet.height, layout.height);
    EXPECT_EQ(layout.magnify, 8);                               // 256 / 32
    const float range = std::hypot(21.0f, 11.0f, 0.5f) - 5.0f;  // largest |distance|: (31, 15, z)
    // The ball's centre texel (10, 4): deep inside, on the blue side; its colour is the map's.
    const glm::vec3 centre = colorAt(sheet, layout.pixelX(0, 10), layout.pixelY(0, 4));
    EXPECT_GT(centre.b, centre.r);
    expectColor(centre, divergingColor(tile.at(10, 4, 0) / range), "centre");
    // A far texel: outside, on the red side.
    const glm::vec3 far = colorAt(sheet, layout.pixelX(1, 26), layout.pixelY(1, 12));
    EXPECT_GT(far.r, far.b);
    expectColor(far, divergingColor(tile.at(26, 12, 1) / range), "far texel");
    // The sign changes between x = 14 (inside, 4.03 from the centre) and x = 15 (outside): 14 is
    // on the contour, 13 is not.
    ASSERT_LT(tile.at(14, 4, 0), 0.0f);
    ASSERT_GT(tile.at(15, 4, 0), 0.0f);
    expectColor(colorAt(sheet, layout.pixelX(0, 14), layout.pixelY(0, 4)), kContourColor,
                "contour");
    EXPECT_NE(colorAt(sheet, layout.pixelX(0, 13), layout.pixelY(0, 4)), kContourColor);
    // y up: texel row y = 0 is the cell's bottom pixel row, y = 15 its top one.
    EXPECT_EQ(layout.pixelY(0, 0) + layout.magnify, layout.cellTop(0) + layout.cellHeight);
    EXPECT_EQ(layout.pixelY(0, 15), layout.cellTop(0));
    // The colour bar's ends: +range on top (the map's red end), -range at the bottom.
    expectColor(colorAt(sheet, layout.barLeft() + 4, layout.barTop()), divergingColor(1.0f),
                "bar top");
    expectColor(colorAt(sheet, layout.barLeft() + 4, layout.barBottom()), divergingColor(-1.0f),
                "bar bottom");
}

TEST(ContactSheet, DivergingMapIsWhiteAtZeroAndClampedBeyondItsEnds) {
    EXPECT_EQ(divergingColor(0.0f), glm::vec3(0.97f));
    EXPECT_EQ(divergingColor(-3.0f), divergingColor(-1.0f));
    EXPECT_EQ(divergingColor(2.0f), divergingColor(1.0f));
    EXPECT_GT(divergingColor(-1.0f).b, divergingColor(-1.0f).r);
    EXPECT_GT(divergingColor(1.0f).r, divergingColor(1.0f).b);
}

// A tile exact but for one texel: the plot shows that texel at the map's red end (the largest
// error, an overestimate) and the others at its white middle.
TEST(ContactSheet, ErrorPlotShowsWhereTheTileErrs) {
    const fs::path file =
        fs::temp_directory_path() / ("distile_plot_" + std::to_string(::getpid()) + ".png");
    Tile tile = ballTile();
    tile.at(20, 8, 1) += 0.5f;
    const auto truth = [](const glm::dvec3& p) {
        return std::hypot(p.x - 10.5, p.y - 4.5, p.z - 1.0) - 5.0;
    };
    writeTileErrorPlot(tile, truth, 100.0, file);
    const Pixels plot = readPixels8(file);
    fs::remove(file);
    const ContactSheetLayout layout(tile.size());
    // The plot has the preview's layout (the pixels below are read by it).
    ASSERT_EQ(plot.width, layout.width);
    ASSERT_EQ(plot.height, layout.height);
    expectColor(colorAt(plot, layout.pixelX(1, 20), layout.pixelY(1, 8)), divergingColor(1.0f),
                "planted error");
    expectColor(colorAt(plot, layout.pixelX(1, 26), layout.pixelY(1, 12)), divergingColor(0.0f),
                "exact texel");
    expectColor(colorAt(plot, layout.pixelX(0, 14), layout.pixelY(0, 4)), kContourColor,
                "the truth's surface");
}

TEST_F(ViewCommand, CheckPlotIsWrittenBesideTheReport) {
    ASSERT_EQ(run({"bake", "chainmail", "--size", "64x64x8", "-o", "tile.exr"}).status, 0);
    // A tile this coarse fails check's tolerances (exit 1): the plot is written all the same.
    const RunResult check = run({"check", "tile.exr", "--samples", "1000", "--plot", "plot.png"});
    ASSERT_EQ(check.status, 1) << check.err;
    EXPECT_EQ(readPixels8(path("plot.png")).width, ContactSheetLayout({64, 64, 8}).width);
    EXPECT_EQ(expectInputError({"check", "tile.exr", "--plot", "plot.tif"}, "plot.tif",
                               {"--plot", ".png"})
                  .status,
              2);
}

TEST_F(ViewCommand, PreviewOfTheChainMailTileIsWritten) {
    ASSERT_EQ(run({"bake", "chainmail", "--size", "64x64x8", "-o", "tile.exr"}).status, 0);
    const RunResult preview = run({"preview", "tile.exr", "-o", "preview.png"});
    ASSERT_EQ(preview.status, 0) << preview.err;
    EXPECT_TRUE(preview.err.empty()) << preview.err;  // labelled: the font was found
    const Pixels sheet = readPixels8(path("preview.png"));
    EXPECT_EQ(sheet.width, ContactSheetLayout({64, 64, 8}).width);
}

TEST_F(ViewCommand, BadInputIsRefusedWithoutOutput) {
    ASSERT_EQ(run({"bake", "chainmail", "--size", "32x32x4", "-o", "tile.exr"}).status, 0);
    writeText(path("broken.exr"), "not an exr");
    EXPECT_EQ(
        expectInputError({"view", "absent.exr", "-o", "page.html"}, "page.html", {"absent.exr"})
            .status,
        2);
    EXPECT_EQ(
        expectInputError({"view", "broken.exr", "-o", "page.html"}, "page.html", {"broken.exr"})
            .status,
        2);
    EXPECT_EQ(expectInputError({"view", "tile.exr", "-o", "page.png"}, "page.png", {"-o", ".html"})
                  .status,
              2);
    EXPECT_EQ(expectInputError({"view", "tile.exr", "-o", "page.html", "--object", "cube"},
                               "page.html", {"--object", "cube", "plane or sphere"})
                  .status,
              2);
    EXPECT_EQ(expectInputError({"view", "tile.exr", "-o", "page.html", "--depth", "-1"},
                               "page.html", {"--depth", "> 0"})
                  .status,
              2);
    // Values the page cannot show: uv beyond float's fraction, shells deeper than the object.
    const std::vector<std::pair<std::vector<std::string>, std::vector<std::string>>> beyond = {
        {{"--uv-scale", "1e30", "4"}, {"--uv-scale", "1e+30", "at most 65536"}},
        {{"--depth", "1e30"}, {"--depth", "at most 4", "plane's size"}},
        {{"--sphere-depth", "2"}, {"--sphere-depth", "at most 1", "sphere's radius"}},
    };
    for (const auto& [flags, keywords] : beyond) {
        std::vector<std::string> arguments = {"view", "tile.exr", "-o", "page.html"};
        arguments.insert(arguments.end(), flags.begin(), flags.end());
        const RunResult refused = run(arguments);
        EXPECT_EQ(refused.status, 2) << refused.err;
        for (const std::string& keyword : keywords)
            EXPECT_NE(refused.err.find(keyword), std::string::npos) << refused.err;
        EXPECT_FALSE(fs::exists(path("page.html")));
    }
    EXPECT_EQ(
        expectInputError({"preview", "broken.exr", "-o", "sheet.png"}, "sheet.png", {"broken.exr"})
            .status,
        2);
    EXPECT_EQ(
        expectInputError({"preview", "tile.exr", "-o", "sheet.jpg"}, "sheet.jpg", {"-o", ".png"})
            .status,
        2);
}

// The page holds the shader as shipped and the whole tile: the half floats of its distances.
TEST(TilePage, EmbedsTheShaderAndTheTile) {
    const Tile tile = ballTile();
    const std::string page = tilePageHtml(tile, "ball <test>");
    EXPECT_NE(page.find(referenceShaderSource()), std::string::npos);
    EXPECT_NE(page.find("ball &lt;test&gt;"), std::string::npos);
    EXPECT_EQ(page.find("@TILE_JSON@"), std::string::npos);
    const std::string key = "\"halfFloatsBase64\":\"";
    const std::size_t start = page.find(key);
    ASSERT_NE(start, std::string::npos);
    const std::size_t end = page.find('"', start + key.size());
    EXPECT_EQ(end - start - key.size(), (tile.size().texelCount() * 2 + 2) / 3 * 4);
}

}  // namespace
}  // namespace distile
