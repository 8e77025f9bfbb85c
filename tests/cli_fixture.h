/// @file
/// The fixture of the end-to-end tests of the `distile` command (cli_test.cpp,
/// cli_hardening_test.cpp): run the built binary in a fresh folder per test and look at its exit
/// status, its stderr lines and the files it left. DISTILE_BINARY is the path of the executable
/// (tests/CMakeLists.txt).
#pragma once

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace distile {

namespace fs = std::filesystem;

/// What one run of the command gave.
struct RunResult {
    int status = -1;  ///< exit status; -1 if it did not exit normally (crash, signal)
    std::string out;
    std::string err;

    std::vector<std::string> errLines() const {
        std::vector<std::string> lines;
        std::istringstream in(err);
        for (std::string line; std::getline(in, line);) lines.push_back(line);
        return lines;
    }
};

inline std::string readText(const fs::path& file) {
    std::ifstream in(file, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

inline void writeText(const fs::path& file, const std::string& text) {
    std::ofstream out(file, std::ios::binary);
    out << text;
}

/// Single-quoted for /bin/sh: safe for any character.
inline std::string shellQuote(const std::string& text) {
    std::string quoted = "'";
    for (char c : text) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return quoted + "'";
}

/// Each test runs the command in its own empty folder `work()`; stdout and stderr go to a
/// sibling folder so that `work()` holds only what the command wrote.
class Cli : public ::testing::Test {
  protected:
    void SetUp() override {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        root_ = fs::temp_directory_path() /
                ("distile_cli_" + std::to_string(::getpid()) + "_" + info->name());
        fs::remove_all(root_);
        fs::create_directories(work());
        fs::create_directories(root_ / "logs");
    }
    void TearDown() override {
        std::error_code ignored;
        fs::remove_all(root_, ignored);
    }

    /// Bounds for the runs of one test: at most `seconds` of wall time and `memoryKiB` of
    /// address space (ulimit -v); files of at most `fileBlocks` 512-byte blocks (ulimit -f:
    /// a longer write fails with EFBIG, as on a full disk, SIGXFSZ ignored).
    struct RunLimits {
        int seconds = 0;  ///< 0: unbounded
        long long memoryKiB = 0;
        long long fileBlocks = 0;  ///< 0: unbounded
    };
    void limitRuns(RunLimits limits) { limits_ = limits; }

    fs::path work() const { return root_ / "work"; }
    fs::path path(const std::string& name) const { return work() / name; }

    /// Runs `distile <arguments>` in work() (`program`: another copy of distile).
    RunResult run(const std::vector<std::string>& arguments,
                  const fs::path& program = DISTILE_BINARY) const {
        const fs::path outFile = root_ / "logs" / "stdout.txt";
        const fs::path errFile = root_ / "logs" / "stderr.txt";
        std::string command = "cd " + shellQuote(work().string()) + " && ";
        if (limits_.fileBlocks > 0)
            command += "ulimit -f " + std::to_string(limits_.fileBlocks) + " && ";
        if (limits_.seconds > 0) {
            // A run beyond its limits fails (timeout's status 124, or an allocation refused)
            // instead of holding up or swapping out the test machine.
            command += "ulimit -v " + std::to_string(limits_.memoryKiB) + " && timeout " +
                       std::to_string(limits_.seconds) + " ";
        }
        command += shellQuote(program.string());
        for (const std::string& argument : arguments) command += " " + shellQuote(argument);
        command +=
            " </dev/null >" + shellQuote(outFile.string()) + " 2>" + shellQuote(errFile.string());
        const int wait = std::system(command.c_str());
        RunResult result;
        result.status = (wait != -1 && WIFEXITED(wait)) ? WEXITSTATUS(wait) : -1;
        result.out = readText(outFile);
        result.err = readText(errFile);
        return result;
    }

    std::set<std::string> workEntries() const {
        std::set<std::string> names;
        for (const auto& entry : fs::directory_iterator(work())) {
            names.insert(entry.path().filename().string());
        }
        return names;
    }

    /// Runs a command that must fail on bad input: a non-zero exit (not a crash), exactly one line
    /// on stderr starting "distile: error:" that contains every one of `keywords`, no `output`
    /// file and nothing new (no partial or temporary file) in the folder. Returns the run, for
    /// what a caller asserts further (its exit status).
    RunResult expectInputError(const std::vector<std::string>& arguments, const std::string& output,
                               std::initializer_list<std::string> keywords) const {
        std::string shown = "distile";
        for (const std::string& argument : arguments) shown += " " + argument;
        SCOPED_TRACE(shown);
        const std::set<std::string> before = workEntries();
        const RunResult result = run(arguments);
        EXPECT_GT(result.status, 0) << "stderr: " << result.err;
        const std::vector<std::string> lines = result.errLines();
        EXPECT_EQ(lines.size(), 1u) << "stderr: " << result.err;
        if (lines.size() != 1) return result;
        EXPECT_EQ(lines[0].rfind("distile: error:", 0), 0u) << lines[0];
        for (const std::string& keyword : keywords) {
            EXPECT_NE(lines[0].find(keyword), std::string::npos)
                << "'" << keyword << "' missing from: " << lines[0];
        }
        EXPECT_FALSE(fs::exists(path(output))) << output;
        EXPECT_EQ(workEntries(), before) << "files were left behind";
        return result;
    }

    /// Writes a scene file and expects `render` of it to fail naming `keywords`.
    void expectSceneError(const std::string& sceneJson,
                          std::initializer_list<std::string> keywords) {
        writeText(path("scene.json"), sceneJson);
        expectInputError({"render", "scene.json", "-o", "out.png"}, "out.png", keywords);
    }

  private:
    fs::path root_;
    RunLimits limits_;
};

}  // namespace distile
