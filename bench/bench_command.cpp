// distile bench: run time against error on the flat chain-mail sheet, distile's sweeps next to the
// peers a user would otherwise pick, all against the analytic reference render; and the curved and
// planar shell marches on the torus on the sheet against its world reference.
#include <Imath/half.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "bake/bake.h"
#include "bench/bench_common.h"
#include "bench/peers/peers.h"
#include "bench/speed_bench.h"
#include "bench/stress/stress_cases.h"
#include "cli/app.h"
#include "cli/arguments.h"
#include "cli/commands.h"
#include "common/error.h"
#include "render/compare.h"
#include "render/renderer.h"
#include "scene/scene_file.h"

namespace distile::cli {

namespace fs = std::filesystem;

namespace {

enum class Storage { Float32, Half16, Byte8 };

const char* storageName(Storage storage) {
    switch (storage) {
        case Storage::Float32:
            return "float";
        case Storage::Half16:
            return "half";
        case Storage::Byte8:
            return "8-bit";
    }
    return "?";
}

/// The tile as it reads back from `storage`: half rounds each distance to the nearest half; 8-bit
/// is ch. 8's normalisation (sampler/tile_io.h writeTilePng): clamp(d / D, 0, 1) in 255 codes.
std::shared_ptr<const Tile> storedAs(const std::shared_ptr<const Tile>& tile, Storage storage) {
    if (storage == Storage::Float32) return tile;
    auto stored = std::make_shared<Tile>(*tile);
    const float depth = float(tile->size().depth);
    for (float& distance : stored->distancesTexels()) {
        if (storage == Storage::Half16) {
            distance = float(Imath::half(distance));
        } else {
            const float code = std::round(std::clamp(distance / depth, 0.0f, 1.0f) * 255.0f);
            distance = code / 255.0f * depth;
        }
    }
    return stored;
}

/// One measured configuration: distile's or a peer's.
struct Row {
    std::string group;  ///< which sweep: size, storage, filter, budget, peer
    std::string label;
    std::string tile;  ///< WxHxD
    std::string storage = "float";
    std::string filter = "trilinear";
    std::string method = "budgeted";
    int budget = 16;
    /// Wall time of a frame: distile's render of its prepared scene (no shadows), a peer's trace
    /// of its built scene.
    double seconds = 0.0;
    /// What comes before the frames: distile's scene preparation (PreparedScene), a peer's build.
    double setupSeconds = 0.0;
    double memoryMiB = 0.0;  ///< tile, or the peer's scene
    double convergedShare = 0.0;
    RenderComparison error;
    bool peer = false;
    /// Rendered from the torus on the sheet and compared with its world reference (the curved-shell
    /// series), not from the sheet against the analytic reference: beside the front, not on it.
    bool torus = false;
    bool paretoFront = false;
    /// distile's sheet rows: what they rendered, to render it again beside the peers.
    std::shared_ptr<const Scene> scene;
    std::optional<RenderOptions> options;
    /// Embree rows: distile rows (index into the rows) rendered again before each of this
    /// configuration's traces, with the fastest of those renders' times, seconds.
    std::vector<std::pair<std::size_t, double>> pairedDistileSeconds;
};

/// The series of the torus on the sheet, one per shell mapping.
std::string torusGroup(ShellMapping mapping) {
    return std::string(shellMappingName(mapping)) + " shell, torus on sheet";
}

double tileMiB(const Tile& tile, Storage storage) {
    const double bytes = storage == Storage::Float32 ? 4.0 : storage == Storage::Half16 ? 2.0 : 1.0;
    return double(tile.distancesTexels().size()) * bytes / (1024.0 * 1024.0);
}

/// Timed runs of every distile row and every Embree configuration: the row's time is the fastest
/// of them. Disturbances on a shared machine only add time, so the minimum is the least disturbed
/// measure of the work (with medians of 5, the default's ratio to Embree moved by about 30% from
/// run to run).
constexpr int kRunsPerRow = 5;

/// Coverage mismatch a distile row may have beyond the row it is compared with (0.5% of the
/// pixels): a row that misses more pixels does not match the other's error.
constexpr double kCoverageMismatchSlack = 0.005;

/// True for a distile row of the sheet (neither a peer nor the torus).
bool isDistileSheet(const Row& row) {
    return !row.peer && !row.torus;
}

/// True when `other`, another distile sheet row, is at least as accurate as `row`: no larger mean
/// hit error and no more coverage mismatch (within kCoverageMismatchSlack).
bool asAccurate(const Row& other, const Row& row) {
    return isDistileSheet(other) && &other != &row &&
           other.error.meanHitErrorTexels <= row.error.meanHitErrorTexels &&
           other.error.coverageMismatchShare <=
               row.error.coverageMismatchShare + kCoverageMismatchSlack;
}

/// distile's sheet rows not dominated in (seconds, mean hit error) by another of them (with no
/// more coverage mismatch, within 0.5%) get paretoFront; peers and the torus rows are shown beside
/// the front.
void markParetoFront(std::vector<Row>& rows) {
    for (Row& row : rows) {
        if (!isDistileSheet(row)) continue;
        row.paretoFront = std::none_of(rows.begin(), rows.end(), [&](const Row& other) {
            return asAccurate(other, row) && other.seconds <= row.seconds &&
                   (other.seconds < row.seconds ||
                    other.error.meanHitErrorTexels < row.error.meanHitErrorTexels);
        });
    }
}

/// How much slower than the front a distile row may be in the sweep and still be rendered again
/// beside the peers: the sweep's times are the fastest of kRunsPerRow renders in one spell of the
/// machine, and rows a few percent apart swap places from run to run, so a row the sweep's noise
/// pushed off the front still gets its paired time.
constexpr double kNearFrontSlack = 1.25;

/// True for a distile sheet row that no other is faster than by more than kNearFrontSlack at the
/// same or a lower mean hit error (with no more coverage mismatch, within 0.5%): the Pareto front
/// and the rows near it.
bool nearParetoFront(const std::vector<Row>& rows, const Row& row) {
    return isDistileSheet(row) && std::none_of(rows.begin(), rows.end(), [&](const Row& other) {
               return asAccurate(other, row) && other.seconds * kNearFrontSlack < row.seconds;
           });
}

/// True for a row of the Embree peer (any configuration).
bool isEmbree(const Row& row) {
    return row.peer && row.label.rfind("embree", 0) == 0;
}

/// Of the distile rows paired with Embree row `embree` (timed alongside its traces), the fastest
/// whose mean hit error is at most Embree's, with no more coverage mismatch than Embree's (plus
/// kCoverageMismatchSlack): its index and paired time; nullopt when none.
std::optional<std::pair<std::size_t, double>> fastestPairedWithin(const std::vector<Row>& rows,
                                                                  const Row& embree) {
    std::optional<std::pair<std::size_t, double>> fastest;
    for (const auto& [index, seconds] : embree.pairedDistileSeconds) {
        const Row& r = rows[index];
        if (r.error.meanHitErrorTexels > embree.error.meanHitErrorTexels ||
            r.error.coverageMismatchShare >
                embree.error.coverageMismatchShare + kCoverageMismatchSlack)
            continue;
        if (!fastest || seconds < fastest->second) fastest = std::pair{index, seconds};
    }
    return fastest;
}

/// The paired time of distile row `index` in Embree row `embree`'s run; NaN when not paired.
double pairedSeconds(const Row& embree, std::size_t index) {
    for (const auto& [paired, seconds] : embree.pairedDistileSeconds)
        if (paired == index) return seconds;
    return std::nan("");
}

/// distile's default configuration on the sheet (tile 256x256x16, float, trilinear, budgeted with
/// the default budget), the row rendered on the sheet's own scene.
const Row* distileDefault(const std::vector<Row>& rows) {
    for (const Row& r : rows)
        if (isDistileSheet(r) && r.options && r.tile == "256x256x16" && r.storage == "float" &&
            r.filter == "trilinear" && r.method == marchMethodName(MarchMethod::Budgeted) &&
            r.budget == MarchSettings{}.maxIterations)
            return &r;
    return nullptr;
}

/// The Embree row to hold distile's default against: the one whose mean hit error is nearest
/// above (or equal to) `meanErrorTexels`, the most accurate Embree that is no more accurate than
/// distile (the fastest of them if several share that error); null when every Embree row is more
/// accurate.
const Row* embreeNearestAbove(const std::vector<Row>& rows, double meanErrorTexels) {
    const Row* nearest = nullptr;
    for (const Row& r : rows) {
        if (!isEmbree(r) || r.error.meanHitErrorTexels < meanErrorTexels) continue;
        if (!nearest || r.error.meanHitErrorTexels < nearest->error.meanHitErrorTexels ||
            (r.error.meanHitErrorTexels == nearest->error.meanHitErrorTexels &&
             r.seconds < nearest->seconds))
            nearest = &r;
    }
    return nearest;
}

/// Embree's fastest row at a mean hit error at most `meanErrorTexels`; null when none.
const Row* fastestEmbreeWithin(const std::vector<Row>& rows, double meanErrorTexels) {
    const Row* fastest = nullptr;
    for (const Row& r : rows)
        if (isEmbree(r) && r.error.meanHitErrorTexels <= meanErrorTexels &&
            (!fastest || r.seconds < fastest->seconds))
            fastest = &r;
    return fastest;
}

/// The largest distile / Embree time ratio that meets the goal: distile in at most half the time
/// of Embree at the error nearest above its own.
constexpr double kGoalDistileOverEmbree = 0.5;

/// The report's section on distile against Embree's curve, with its verdicts.
std::string embreeSection(const std::vector<Row>& rows) {
    std::ostringstream md;
    md.precision(4);
    bool anyEmbree = false;
    for (const Row& r : rows) anyEmbree = anyEmbree || isEmbree(r);
    if (!anyEmbree) return "";
    md << "## distile against Embree's curve\n\n"
       << "Each Embree configuration against distile's fastest configuration at the same or a "
          "lower mean hit error (and no more than 0.5% more coverage mismatch) among distile's "
          "Pareto front, the rows near it (at most 25% slower in the sweep) and its default. "
          "Before each of Embree's traces ("
       << kRunsPerRow
       << " of one built scene) "
          "every one of those distile configurations renders once, so both are timed in the same "
          "spell of the machine; the times here are the fastest of those runs (the other tables "
          "hold the sweep's own). Disturbances on a shared machine only add time: the fastest "
          "run is the least disturbed measure of each one's work.\n\n"
       << "| Embree configuration | Embree s | Embree mean err | distile at <= that error | "
          "distile s | distile mean err | distile / Embree |\n|---|---|---|---|---|---|---|\n";
    bool everyLevel = true;
    for (const Row& r : rows) {
        if (!isEmbree(r)) continue;
        const auto match = fastestPairedWithin(rows, r);
        everyLevel = everyLevel && match && match->second < r.seconds;
        md << "| " << r.label << " | " << r.seconds << " | " << r.error.meanHitErrorTexels << " | ";
        if (match)
            md << rows[match->first].label << " | " << match->second << " | "
               << rows[match->first].error.meanHitErrorTexels << " | " << match->second / r.seconds
               << " |\n";
        else
            md << "none | - | - | - |\n";
    }
    md << "\n";
    const Row* own = distileDefault(rows);
    std::string goalVerdict = "not measured: distile's default row is missing";
    if (own) {
        const auto ownIndex = std::size_t(own - rows.data());
        const double ownError = own->error.meanHitErrorTexels;
        const Row* above = embreeNearestAbove(rows, ownError);
        const Row* within = fastestEmbreeWithin(rows, ownError);
        md << "distile's default (" << own->label << ", mean " << ownError << " texel):\n\n";
        if (within)
            md << "- Embree's time at distile's error (its fastest configuration at that error "
                  "or lower): "
               << within->label << ", " << within->seconds << " s against distile's "
               << pairedSeconds(*within, ownIndex)
               << " s; distile / Embree = " << pairedSeconds(*within, ownIndex) / within->seconds
               << ".\n";
        else
            md << "- Embree's time at distile's error: no Embree configuration here is that "
                  "accurate.\n";
        if (above) {
            const double ratio = pairedSeconds(*above, ownIndex) / above->seconds;
            md << "- Embree nearest above distile's error: " << above->label << ", "
               << above->seconds << " s at " << above->error.meanHitErrorTexels
               << " texel, against distile's " << pairedSeconds(*above, ownIndex)
               << " s; distile / Embree = " << ratio << ".\n";
            goalVerdict = std::string(ratio <= kGoalDistileOverEmbree ? "**pass**" : "**FAIL**") +
                          " distile's default / Embree nearest above its error = " +
                          std::to_string(ratio).substr(0, 5) + " (target <= 0.5)";
        } else {
            md << "- Embree nearest above distile's error: none (every Embree configuration is "
                  "more accurate).\n";
            goalVerdict =
                "not measured: every Embree configuration is more accurate than "
                "distile's default";
        }
    }
    md << "\nVerdicts:\n\n- " << goalVerdict << "\n- " << (everyLevel ? "**pass**" : "**FAIL**")
       << " at every Embree error level distile has a faster configuration at the same or lower "
          "error\n\n";
    return md.str();
}

std::string csvOf(const std::vector<Row>& rows, int threads, int width, int height) {
    std::ostringstream csv;
    csv << "group,label,tile,storage,filter,method,budget,seconds,setup_seconds,memory_mib,"
           "converged_share,hit_error_mean_texels,hit_error_p99_texels,hit_error_max_texels,"
           "coverage_mismatch_share,normal_error_mean_deg,pareto_front,threads,width,height,scene,"
           "reference,interior_hit_error_mean_texels,interior_hit_error_p99_texels\n";
    csv.precision(6);
    for (const Row& r : rows) {
        csv << r.group << ",\"" << r.label << "\"," << r.tile << "," << r.storage << "," << r.filter
            << "," << r.method << "," << r.budget << "," << r.seconds << "," << r.setupSeconds
            << "," << r.memoryMiB << "," << r.convergedShare << "," << r.error.meanHitErrorTexels
            << "," << r.error.p99HitErrorTexels << "," << r.error.maxHitErrorTexels << ","
            << r.error.coverageMismatchShare << "," << r.error.meanNormalErrorDeg << ","
            << (r.paretoFront ? 1 : 0) << "," << threads << "," << width << "," << height << ","
            << (r.torus ? "torus on sheet,world" : "sheet,analytic") << ","
            << r.error.interior.meanHitErrorTexels << "," << r.error.interior.p99HitErrorTexels
            << "\n";
    }
    return csv.str();
}

/// gnuplot script: seconds (log) against mean hit error (log), one point style per group, the
/// Pareto front as a line, every point labelled.
std::string gnuplotScript(const std::vector<Row>& rows, const fs::path& png) {
    std::ostringstream gp;
    gp << "set terminal pngcairo size 1400,900 enhanced font 'Sans,11'\n"
       << "set output '" << png.string() << "'\n"
       << "set title 'distile bench: render time against mean hit error (flat chain-mail sheet "
          "against the analytic reference; torus on sheet against the world reference)'\n"
       << "set xlabel 'time per frame, seconds (log)'\nset ylabel 'mean hit error, texels (log)'\n"
       << "set logscale xy\nset grid\nset key outside right top\nset datafile separator ','\n";
    std::vector<std::string> groups;
    for (const Row& r : rows)
        if (std::find(groups.begin(), groups.end(), r.group) == groups.end())
            groups.push_back(r.group);
    gp << "plot ";
    // Embree's recommended configurations are a curve; the other peers' points are stars.
    auto style = [](const std::string& group, std::size_t g) {
        if (group == "embree") return std::string("linespoints pt 3");
        if (group == "peer" || group == "embree, other") return std::string("points pt 3");
        return "points pt " + std::to_string(5 + 2 * int(g % 4));
    };
    constexpr std::array<const char*, 10> kColors{"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728",
                                                  "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
                                                  "#000000", "#17becf"};
    for (std::size_t g = 0; g < groups.size(); ++g) {
        gp << "'-' using 1:2 with " << style(groups[g], g) << " ps 1.6 lc rgb '"
           << kColors[g % kColors.size()] << "' title '" << groups[g] << "', ";
    }
    gp << "'-' using 1:2 with lines lw 2 lc rgb '#444444' title 'distile Pareto front', "
       << "'-' using 1:2:3 with labels offset 0.8,0.6 left font 'Sans,8' noenhanced notitle\n";
    auto finite = [](const Row& r) {
        return r.seconds > 0.0 && r.error.meanHitErrorTexels > 0.0 &&
               std::isfinite(r.error.meanHitErrorTexels);
    };
    for (const std::string& group : groups) {
        for (const Row& r : rows)
            if (r.group == group && finite(r))
                gp << r.seconds << "," << r.error.meanHitErrorTexels << "\n";
        gp << "e\n";
    }
    std::vector<Row> front;
    for (const Row& r : rows)
        if (r.paretoFront && finite(r)) front.push_back(r);
    std::sort(front.begin(), front.end(),
              [](const Row& a, const Row& b) { return a.seconds < b.seconds; });
    for (const Row& r : front) gp << r.seconds << "," << r.error.meanHitErrorTexels << "\n";
    gp << "e\n";
    for (const Row& r : rows)
        if (finite(r))
            gp << r.seconds << "," << r.error.meanHitErrorTexels << ",\"" << r.label << "\"\n";
    gp << "e\n";
    return gp.str();
}

/// Runs a command line of our own making (quoted paths); true when it exits 0.
bool runProgram(const std::string& commandLine) {
    return std::system(commandLine.c_str()) == 0;
}

struct ClaimRow {
    std::string detail;
    int budget = 0;
    double convergedShare = 0.0;
};

std::string reportOf(const std::vector<Row>& rows, const std::vector<ClaimRow>& claims,
                     const std::vector<std::string>& notes, int threads, int width, int height,
                     double referenceSeconds, double worldReferenceSeconds, bool plotted) {
    std::ostringstream md;
    md.precision(4);
    md << "# distile bench\n\n"
       << "Flat chain-mail sheet (data/scenes/sheet.json: a plane of 4 x 4 default chain-mail "
          "tiles, camera about 35 degrees above it), "
       << width << "x" << height << ", " << threads
       << " threads. Every row is timed in this run and compared with the analytic reference "
          "render (double precision, 512 sphere-tracing steps, epsilon 0.001 texel; "
       << referenceSeconds
       << " s). distile rows are frames without shadows (primary rays, march, normals, "
          "shading) of a prepared scene, timed without AOVs (the fastest of "
       << kRunsPerRow
       << "; the error from one "
          "more render with them); peer rows are their primary-ray trace times of a built scene. "
          "Both set-ups (distile's scene preparation: BVH, tile layout and empty space, shell "
          "map; a peer's build) are in the setup column. Hit error: distance along the "
          "ray to the reference hit, in texels. The two torus-on-sheet series are another scene "
          "against another truth (see Curved shells below).\n\n";
    if (plotted) md << "![time against error](pareto.png)\n\n";
    md << "## distile's Pareto front (time against mean hit error)\n\n";
    for (const Row& r : rows)
        if (r.paretoFront)
            md << "- **" << r.label << "**: " << r.seconds << " s, mean "
               << r.error.meanHitErrorTexels << " texel\n";
    md << "\nPeers, beside the front:\n\n";
    for (const Row& r : rows)
        if (r.peer)
            md << "- **" << r.label << "**: " << r.seconds << " s trace (" << r.setupSeconds
               << " s setup, " << r.memoryMiB << " MiB), mean " << r.error.meanHitErrorTexels
               << " texel, coverage mismatch " << 100.0 * r.error.coverageMismatchShare << "%\n";
    md << "\n" << embreeSection(rows);
    md << "## Curved shells: the torus on the sheet\n\n"
       << "data/scenes/torus_on_sheet.json (chain mail on a torus, a curved base, lying on the "
          "sheet) at the same size, rendered with the curved shell march (the default: the ray "
          "follows the shell map prism by prism) and with the planar one (ch. 8: the ray mapped "
          "into texel space once, at its entry), each the fastest of 2 runs, alternated; both "
          "against the world reference (the detail mapped through the curved shell into world "
          "space and traced there; "
       << worldReferenceSeconds
       << " s, its build included). Interior: the pixels where both hit, away from silhouettes "
          "and depth jumps (render/compare.h); all: every pixel where both hit. On the plot they "
          "are their own two series, beside the sheet's front.\n\n"
          "| shell | time s | interior mean | interior p99 | all mean | all p99 | coverage "
          "mismatch | normal err deg |\n|---|---|---|---|---|---|---|---|\n";
    const Row* curvedRow = nullptr;
    const Row* planarRow = nullptr;
    for (const Row& r : rows) {
        if (!r.torus) continue;
        (r.group == torusGroup(ShellMapping::Curved) ? curvedRow : planarRow) = &r;
        md << "| " << r.label << " | " << r.seconds << " | " << r.error.interior.meanHitErrorTexels
           << " | " << r.error.interior.p99HitErrorTexels << " | " << r.error.meanHitErrorTexels
           << " | " << r.error.p99HitErrorTexels << " | " << 100.0 * r.error.coverageMismatchShare
           << "% | " << r.error.meanNormalErrorDeg << " |\n";
    }
    if (curvedRow && planarRow)
        md << "\nCurved / planar time: " << curvedRow->seconds / planarRow->seconds << ".\n";
    md << "\n## All rows\n\n| group | configuration | time s | setup s | memory MiB | converged | "
          "mean err | p99 err | coverage mismatch | normal err deg | front |\n"
       << "|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (const Row& r : rows) {
        md << "| " << r.group << " | " << r.label << " | " << r.seconds << " | " << r.setupSeconds
           << " | " << r.memoryMiB << " | "
           << (r.peer ? std::string("-") : std::to_string(r.convergedShare).substr(0, 5)) << " | "
           << r.error.meanHitErrorTexels << " | " << r.error.p99HitErrorTexels << " | "
           << 100.0 * r.error.coverageMismatchShare << "% | " << r.error.meanNormalErrorDeg << " | "
           << (r.paretoFront ? "yes" : "") << " |\n";
    }
    md << "\n## GPU Gems 2 ch. 8's claims on this data\n\n"
       << "Ch. 8 says 16 sphere-tracing iterations are enough for the chain mail and 8 for a "
          "smooth "
          "height field. Criterion here: at least 99% of the rays that enter a shell converge "
          "(reach the surface within epsilon 0.02 texel, or the floor) with plain sphere tracing "
          "(ch. 8's method).\n\n| detail | budget | converged share | enough? "
          "|\n|---|---|---|---|\n";
    for (const ClaimRow& c : claims) {
        md << "| " << c.detail << " | " << c.budget << " | " << c.convergedShare << " | "
           << (c.convergedShare >= 0.99 ? "yes" : "no") << " |\n";
    }
    md << "\nThe budgeted march (distile's default) converges on every ray by construction; its "
          "error is in the budget rows above.\n";
    if (!notes.empty()) {
        md << "\n## Notes\n\n";
        for (const std::string& note : notes) md << "- " << note << "\n";
    }
    return md.str();
}

/// A CSV field: quoted, inner quotes doubled.
std::string csvField(const std::string& text) {
    std::string quoted = "\"";
    for (char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
    return quoted + "\"";
}

/// A markdown table cell: '|' escaped.
std::string tableCell(const std::string& text) {
    std::string escaped;
    for (char c : text) escaped += c == '|' ? std::string("\\|") : std::string(1, c);
    return escaped;
}

/// `distile bench --stress -o DIR`: runs the numerical stress cases
/// (bench/stress/stress_cases.h), writes DIR/stress.md and DIR/stress.csv, prints one line per
/// case and exits with status 1 when a case failed.
void runStressReport(const fs::path& outputDir) {
    std::error_code error;
    fs::create_directories(outputDir, error);
    if (error)
        throw InputError("-o: cannot create the folder '" + outputDir.string() +
                         "': " + error.message());
    std::printf("bench: numerical stress cases\n");
    std::fflush(stdout);
    const std::vector<StressCase> cases = runStressCases();
    std::ostringstream md, csv;
    md << "# distile bench --stress\n\n"
          "The numerical-stability stress cases, each against a known answer (a "
          "plane's exact hit, the same scene near the origin, the analytic chain mail). Error: "
          "the case's figure against that answer, in texels; pass: error within tolerance, no "
          "NaN/Inf pixel and every other expectation held (tests/stress_test.cpp asserts the "
          "same).\n\n"
          "| case | expected | measured | error (texels) | tolerance (texels) | non-finite | pass "
          "|\n|---|---|---|---|---|---|---|\n";
    csv << "case,expected,measured,error_texels,tolerance_texels,non_finite_pixels,passed\n";
    csv.precision(6);
    std::vector<std::string> failedChecks;
    int failed = 0;
    for (const StressCase& c : cases) {
        char figures[96];
        std::snprintf(figures, sizeof figures, "%.3g | %.3g", c.errorTexels, c.toleranceTexels);
        md << "| " << tableCell(c.name) << " | " << tableCell(c.expected) << " | "
           << tableCell(c.measured) << " | " << figures << " | " << c.nonFinitePixels << " | "
           << (c.passed ? "yes" : "**no**") << " |\n";
        csv << csvField(c.name) << "," << csvField(c.expected) << "," << csvField(c.measured) << ","
            << c.errorTexels << "," << c.toleranceTexels << "," << c.nonFinitePixels << ","
            << (c.passed ? 1 : 0) << "\n";
        std::printf("  %-48s %s  error %.3g (tolerance %.3g) texels, %llu non-finite\n",
                    c.name.c_str(), c.passed ? "pass" : "FAIL", c.errorTexels, c.toleranceTexels,
                    (unsigned long long)c.nonFinitePixels);
        failed += c.passed ? 0 : 1;
        for (const StressCheck& check : c.checks)
            if (!check.held) {
                failedChecks.push_back(c.name + ": " + check.what);
                std::printf("    failed: %s\n", check.what.c_str());
            }
    }
    if (!failedChecks.empty()) {
        md << "\n## Failed expectations\n\n";
        for (const std::string& line : failedChecks) md << "- " << line << "\n";
    }
    writeText(outputDir / "stress.md", md.str());
    writeText(outputDir / "stress.csv", csv.str());
    std::printf("bench: %d of %zu stress cases passed; wrote %s, stress.csv\n",
                int(cases.size()) - failed, cases.size(),
                fs::absolute(outputDir / "stress.md").string().c_str());
    std::fflush(stdout);
    if (failed > 0) std::exit(kExitFailure);  // a case failed: the work failed (cli/app.h)
}

/// The skips for ch. 8's plain sphere tracing: no empty-space skipping, which would change the
/// march whose convergence the chapter's claims are about.
RenderSkips chapter8Skips() {
    RenderSkips skips;
    skips.emptySpace = false;
    return skips;
}

/// The Embree configurations of the sweep: the plain one (one ray per call, triangles, the
/// default BVH, 0.02 texel), and Embree as its documentation recommends for camera rays (native
/// packets over pixel tiles, quads, the high-quality BVH) at four tessellation bounds, plus the
/// packets with triangles and the default BVH at 0.05 texel to show what each choice gives.
std::vector<EmbreePeerOptions> embreeConfigurations() {
    const int packet = embreeNativePacketWidth();
    std::vector<EmbreePeerOptions> configurations;
    EmbreePeerOptions plain;
    configurations.push_back(plain);
    if (packet > 1) {
        EmbreePeerOptions packets;
        packets.raysPerPacket = packet;
        packets.tessellationErrorTexels = 0.05;
        configurations.push_back(packets);
        for (double errorTexels : {0.02, 0.05, 0.1, 0.2}) {
            EmbreePeerOptions best = packets;
            best.quads = true;
            best.highQualityBvh = true;
            best.tessellationErrorTexels = errorTexels;
            configurations.push_back(best);
        }
    }
    for (EmbreePeerOptions& options : configurations) options.traceRuns = kRunsPerRow;
    return configurations;
}

void runBench(const BenchArguments& arguments) {
    // Every report writes into -o, made if missing: it must name a folder, not a file.
    if (arguments.outputDir.empty())
        throw InputError("-o: is empty; give the folder for the results");
    if (std::error_code status;
        fs::exists(arguments.outputDir, status) && !fs::is_directory(arguments.outputDir, status)) {
        throw InputError("-o: '" + arguments.outputDir.string() +
                         "' is a file; give the folder for the results (made if missing)");
    }
    if (arguments.stress) {
        runStressReport(arguments.outputDir);
        return;
    }
    if (arguments.speed) {
        runSpeedBench(arguments);
        return;
    }
    const int width = arguments.width > 0 ? arguments.width : (arguments.quick ? 640 : 1280);
    const int height = arguments.height > 0 ? arguments.height : (arguments.quick ? 512 : 1024);
    const int threads =
        int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
    fs::create_directories(arguments.outputDir / "scenes");
    std::vector<Row> rows;
    std::vector<std::string> notes;
    TileCache tiles;
    auto say = [](const std::string& line) {
        std::printf("%s\n", line.c_str());
        std::fflush(stdout);
    };

    auto loadSheet = [&](const Size3& size) {
        const fs::path file =
            arguments.outputDir / "scenes" /
            ("sheet_" + std::to_string(size.width) + "x" + std::to_string(size.height) + "x" +
             std::to_string(size.depth) + ".json");
        return loadBenchScene(file, sheetJson(size), tiles).scene;
    };

    const Size3 defaultSize{256, 256, 16};
    say("bench: baking the default chain mail and rendering the analytic reference (" +
        std::to_string(width) + "x" + std::to_string(height) + ", " + std::to_string(threads) +
        " threads)");
    const Scene sheet = loadSheet(defaultSize);
    RenderOptions referenceOptions = benchRenderOptions(width, height);
    referenceOptions.reference = true;
    const TimedRender reference = timedRender(sheet, referenceOptions);
    const RenderLayersView truth = layers(reference.result);

    // Without a texel scale of its own, a render's hit errors are in the truth's texels.
    const Image noTexelScale(width, height);
    // A row from a timed render of `scene`, compared with `truthOf`, its hit errors in the
    // truth's texels or in the render's own. The sheet's rows take the analytic reference's: the
    // default tile's, in which the peers are measured too (a 512 tile's texels are half as large).
    auto record = [&](Row row, const TimedRender& timed, const Scene& scene,
                      const RenderOptions& options, Storage storage,
                      const RenderLayersView& truthOf, bool inTruthTexels) {
        row.seconds = timed.frameSeconds;
        row.setupSeconds = timed.setupSeconds;
        row.convergedShare = timed.result.stats.convergedShare();
        const RenderLayersView measured = layers(timed.result);
        row.error = compareRenders(inTruthTexels ? RenderLayersView{measured.image, measured.depth,
                                                                    measured.normal, noTexelScale}
                                                 : measured,
                                   truthOf);
        row.memoryMiB = tileMiB(*scene.objects[0].material.tile, storage);
        row.tile = std::to_string(scene.objects[0].material.tile->size().width) + "x" +
                   std::to_string(scene.objects[0].material.tile->size().height) + "x" +
                   std::to_string(scene.objects[0].material.tile->size().depth);
        row.storage = storageName(storage);
        row.filter = options.filter == FilterKind::Trilinear ? "trilinear" : "tricubic";
        row.method = marchMethodName(options.march.method);
        row.budget = options.march.maxIterations;
        char line[256];
        std::snprintf(
            line, sizeof line, "  %-8s %-44s %7.3f s  mean %.4f p99 %.3f texels, converged %.3f",
            row.group.c_str(), row.label.c_str(), row.seconds, row.error.meanHitErrorTexels,
            row.error.p99HitErrorTexels, row.convergedShare);
        say(line);
        rows.push_back(row);
    };
    auto measure = [&](Row row, const Scene& scene, const RenderOptions& options, Storage storage) {
        // The error from a render with AOVs (the depth a comparison reads); the time from renders
        // without them, as a user renders a picture and as the peers trace: writing seven more
        // images is no part of the render.
        RenderOptions timed = options;
        timed.outputAovs = false;
        row.scene = std::make_shared<const Scene>(scene);
        row.options = timed;
        TimedRender render = timedRender(scene, options);
        const TimedRender fastest = fastestRender(scene, timed, kRunsPerRow);
        render.frameSeconds = fastest.frameSeconds;
        render.setupSeconds = fastest.setupSeconds;
        record(std::move(row), render, scene, options, storage, truth, true);
    };
    const RenderOptions defaults = benchRenderOptions(width, height);

    // Tile size (the same chain mail at three resolutions).
    say("bench: tile sizes");
    std::vector<Size3> sizes{{128, 128, 8}, {256, 256, 16}};
    if (!arguments.quick) sizes.push_back({512, 512, 32});
    std::optional<Scene> largeTileSheet;  // the largest tile, for the accuracy rows
    for (const Size3& size : sizes) {
        const Scene scene = size == defaultSize ? sheet : loadSheet(size);
        if (size.width > defaultSize.width) largeTileSheet = scene;
        Row row;
        row.group = "size";
        row.label = "tile " + std::to_string(size.width) + "x" + std::to_string(size.height) + "x" +
                    std::to_string(size.depth);
        measure(row, scene, defaults, Storage::Float32);
    }
    // Storage.
    say("bench: storage");
    for (Storage storage : {Storage::Half16, Storage::Byte8}) {
        Scene scene = sheet;
        scene.objects[0].material.tile = storedAs(sheet.objects[0].material.tile, storage);
        Row row;
        row.group = "storage";
        row.label = std::string("storage ") + storageName(storage);
        measure(row, scene, defaults, storage);
    }
    // Filter.
    say("bench: filters");
    {
        RenderOptions options = defaults;
        options.filter = FilterKind::TricubicBSpline;
        Row row;
        row.group = "filter";
        row.label = "march filter tricubic";
        measure(row, sheet, options, Storage::Float32);
    }
    // Budget x march method.
    say("bench: budgets and march methods");
    const std::vector<int> budgets =
        arguments.quick ? std::vector<int>{8, 16, 32} : std::vector<int>{4, 8, 16, 24, 32, 64};
    const std::vector<MarchMethod> methods{MarchMethod::SphereTracing, MarchMethod::OverRelaxed,
                                           MarchMethod::Budgeted, MarchMethod::Relief,
                                           MarchMethod::FixedSteps};
    std::vector<ClaimRow> claims;
    for (MarchMethod method : methods) {
        for (int budget : budgets) {
            RenderOptions options = defaults;
            options.march.method = method;
            // Ch. 8's claims are about its march as written: from the top face, the whole budget.
            if (method == MarchMethod::SphereTracing) options.skips = chapter8Skips();
            options.march.maxIterations = budget;
            Row row;
            row.group = marchMethodName(method);
            row.label = std::string(marchMethodName(method)) + " " + std::to_string(budget);
            measure(row, sheet, options, Storage::Float32);
            if (method == MarchMethod::SphereTracing)
                claims.push_back({"chain mail (sheet)", budget, rows.back().convergedShare});
        }
    }
    // Accuracy: what distile's lowest errors cost (the budget rows end at the default tile's
    // trilinear error): the larger tile, the tricubic march filter and a finer hit epsilon, each
    // with the budgets they need.
    say("bench: accuracy");
    {
        auto accuracyRow = [&](const std::string& label, const Scene& scene, RenderOptions options,
                               int budget) {
            options.march.maxIterations = budget;
            Row row;
            row.group = "accuracy";
            row.label = label + ", budgeted " + std::to_string(budget);
            measure(row, scene, options, Storage::Float32);
        };
        RenderOptions tricubic = defaults;
        tricubic.filter = FilterKind::TricubicBSpline;
        RenderOptions fineEpsilon = defaults;
        fineEpsilon.march.epsilonTexels = 0.005f;
        for (int budget : {32, 64}) {
            accuracyRow("march filter tricubic", sheet, tricubic, budget);
            accuracyRow("epsilon 0.005", sheet, fineEpsilon, budget);
        }
        // The larger tile's march is twice as long in its texels: it needs about twice the
        // default budget, and reaches its lowest error near 64.
        if (largeTileSheet) {
            for (int budget : {32, 48, 64})
                accuracyRow("tile 512x512x32", *largeTileSheet, defaults, budget);
        }
    }
    // Ch. 8's smooth height field claim: the sheet with a smooth height-field tile.
    say("bench: smooth height field (ch. 8's 8-iteration claim)");
    {
        const HeightImage heights = smoothHeightImage(128);
        BakeOptions bake;
        bake.size = {128, 128, 8};
        Scene field = sheet;
        field.objects[0].material.tile =
            std::make_shared<const Tile>(bakeHeightMap(heights, HeightMapOptions{}, bake).tile);
        field.objects[0].material.analyticDistance = {};
        for (int budget : {4, 8, 16}) {
            RenderOptions options = defaults;
            options.march.method = MarchMethod::SphereTracing;
            options.skips = chapter8Skips();
            options.march.maxIterations = budget;
            options.outputAovs = false;
            const TimedRender timed = timedRender(field, options);
            claims.push_back({"smooth height field", budget, timed.result.stats.convergedShare()});
            say("  height field, sphere tracing " + std::to_string(budget) + ": converged " +
                std::to_string(claims.back().convergedShare));
        }
    }
    // The torus on the sheet (data/scenes/torus_on_sheet.json): the curved and the planar shell
    // march, each the fastest of two runs alternated after an untimed warm-up render, against the
    // world reference at the same size.
    say("bench: torus on sheet, curved and planar shells, against the world reference");
    double worldReferenceSeconds = 0.0;
    {
        const Scene torus = loadBenchScene(arguments.outputDir / "scenes" / "torus_on_sheet.json",
                                           torusOnSheetJson(), tiles)
                                .scene;
        RenderOptions curved = defaults;
        curved.shellMapping = ShellMapping::Curved;
        RenderOptions planar = defaults;
        planar.shellMapping = ShellMapping::Planar;
        timedRender(torus, curved);
        const FastestPair pair = fastestPair(torus, curved, torus, planar, 2);
        const TimedWorldReference world = timedWorldReference(torus, width, height);
        worldReferenceSeconds = world.seconds;
        const RenderLayersView worldTruth = layers(world.result.render);
        for (const auto& [mapping, timed, options] :
             {std::tuple{ShellMapping::Curved, &pair.a, &curved},
              std::tuple{ShellMapping::Planar, &pair.b, &planar}}) {
            Row row;
            row.group = torusGroup(mapping);
            row.label = std::string("torus on sheet, ") + shellMappingName(mapping);
            row.torus = true;
            record(row, *timed, torus, *options, Storage::Float32, worldTruth, false);
        }
        say("  world reference " + std::to_string(world.seconds) + " s");
    }
    // Peers.
    if (arguments.peers) {
        say("bench: peers");
        auto peerRow = [&](const PeerRender& peer, const std::string& group,
                           const std::string& label) {
            if (!peer.available) {
                notes.push_back(label + ": " + peer.unavailableReason);
                say("  " + label + ": " + peer.unavailableReason);
                return;
            }
            // Peers shade nothing and know no texel scale: the reference's converts their depth.
            const Image blank(peer.depth.width, peer.depth.height);
            Row row;
            row.group = group;
            row.label = label;
            row.peer = true;
            row.tile = "-";
            row.storage = "-";
            row.filter = "-";
            row.method = "-";
            row.budget = 0;
            row.seconds = peer.traceSeconds;
            row.setupSeconds = peer.setupSeconds;
            row.memoryMiB = double(peer.memoryBytes) / (1024.0 * 1024.0);
            row.error = compareRenders({blank, peer.depth, peer.normal, noTexelScale}, truth);
            char line[256];
            std::snprintf(line, sizeof line,
                          "  peer     %-44s %7.3f s  mean %.4f p99 %.3f texels, coverage "
                          "mismatch %.4f (setup %.1f s, %.0f MiB)",
                          row.label.c_str(), row.seconds, row.error.meanHitErrorTexels,
                          row.error.p99HitErrorTexels, row.error.coverageMismatchShare,
                          row.setupSeconds, row.memoryMiB);
            say(line);
            rows.push_back(row);
        };
        // distile's front so far, the rows near it and its default, rendered again beside each
        // Embree trace.
        markParetoFront(rows);
        std::vector<std::size_t> paired;
        for (std::size_t i = 0; i < rows.size(); ++i)
            if (rows[i].options &&
                (nearParetoFront(rows, rows[i]) || &rows[i] == distileDefault(rows)))
                paired.push_back(i);
        for (EmbreePeerOptions options : embreeConfigurations()) {
            std::vector<std::vector<double>> pairedRuns(paired.size());
            options.beforeEachTrace = [&] {
                for (std::size_t p = 0; p < paired.size(); ++p)
                    pairedRuns[p].push_back(
                        timedRender(*rows[paired[p]].scene, *rows[paired[p]].options).frameSeconds);
            };
            const PeerRender peer = renderSheetWithEmbree(sheet, width, height, threads, options);
            std::vector<std::pair<std::size_t, double>> pairedSeconds;
            for (std::size_t p = 0; p < paired.size(); ++p) {
                if (!pairedRuns[p].empty())
                    pairedSeconds.emplace_back(
                        paired[p], *std::min_element(pairedRuns[p].begin(), pairedRuns[p].end()));
            }
            // Embree's curve (its recommended configuration at each bound) is a series of its own.
            const bool recommended = options.raysPerPacket > 1 && options.quads;
            peerRow(peer, recommended ? "embree" : "embree, other", embreePeerLabel(options));
            if (peer.available) rows.back().pairedDistileSeconds = std::move(pairedSeconds);
        }
        const fs::path work = arguments.outputDir / "vdb_render";
        fs::create_directories(work);
        peerRow(renderSheetWithVdbRender(sheet, width, height, threads, work), "peer",
                "vdb_render");
        notes.push_back(
            "vdb_render's level set has no floor: pixels where distile and the reference hit the "
            "sheet's solid floor are misses there (its coverage mismatch).");
    }

    markParetoFront(rows);
    const std::string csv = csvOf(rows, threads, width, height);
    writeText(arguments.outputDir / "bench.csv", csv);
    const fs::path script = arguments.outputDir / "pareto.gp";
    writeText(script, gnuplotScript(rows, arguments.outputDir / "pareto.png"));
    const bool plotted = runProgram("gnuplot \"" + script.string() + "\"");
    if (!plotted) notes.push_back("gnuplot failed or is missing (Debian: gnuplot-nox): no plot");
    const std::string report = reportOf(rows, claims, notes, threads, width, height,
                                        reference.seconds, worldReferenceSeconds, plotted);
    writeText(arguments.outputDir / "report.md", report);
    say("bench: wrote " + fs::absolute(arguments.outputDir / "bench.csv").string() + ", " +
        (plotted ? "pareto.png, " : "") + "report.md");
}

}  // namespace

void addBenchCommand(CLI::App& app) {
    auto arguments = std::make_shared<BenchArguments>();
    CLI::App* command = app.add_subcommand(
        "bench",
        "Time against error on the flat chain-mail sheet: tile sizes, storage, filters, budgets "
        "and march methods, next to Embree and vdb_render, all against the analytic reference; "
        "and the torus on the sheet with curved and planar shells against the world reference; "
        "writes bench.csv, pareto.png (gnuplot) and report.md");
    command->add_option("-o,--output", arguments->outputDir, "Folder for the results")
        ->capture_default_str();
    command->add_flag("--quick", arguments->quick,
                      "Reduced sweep at 640x512 (peers included), a few minutes on 2 cores");
    // A callback, not "!--no-peers": the negated flag shows in --help as "--no-peers{false}".
    command->add_flag_callback(
        "--no-peers", [arguments] { arguments->peers = false; }, "Skip Embree and vdb_render");
    command->add_flag("--stress", arguments->stress,
                      "Instead of the sweep: the numerical-stability stress cases, written as "
                      "stress.md and stress.csv; exit 1 when a case fails");
    command
        ->add_flag("--speed", arguments->speed,
                   "Instead of the sweep: the speed report: distile against the peers, "
                   "repetition, every render skip on and off, bake cache, threads, curved against "
                   "planar shells (and each against the world reference); writes speed.md and "
                   "speed.csv")
        ->excludes("--stress");
    command->add_option("--width", arguments->width, "Image width (default 1280, quick 640)")
        ->check(integerRange(16, 16384));
    command->add_option("--height", arguments->height, "Image height (default 1024, quick 512)")
        ->check(integerRange(16, 16384));
    command->callback([arguments] { runBench(*arguments); });
}

}  // namespace distile::cli
