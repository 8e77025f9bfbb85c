/// @file
/// A one-line progress bar on standard error for long work; silent when standard error is not
/// a terminal (logs and CI stay clean).
#pragma once

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <string>

namespace distile::cli {

class ProgressBar {
  public:
    explicit ProgressBar(std::string label)
        : label_(std::move(label)), enabled_(::isatty(STDERR_FILENO) == 1) {}
    ProgressBar(const ProgressBar&) = delete;
    ProgressBar& operator=(const ProgressBar&) = delete;
    ~ProgressBar() {
        if (enabled_ && shownPercent_ >= 0) std::fprintf(stderr, "\r\033[K");
    }

    /// False when standard error is not a terminal: then nobody needs the calls (work that
    /// reports progress can skip what reporting costs).
    bool enabled() const { return enabled_; }

    void operator()(double fractionDone) {
        if (!enabled_) return;
        const int percent = int(fractionDone * 100.0 + 0.5);
        if (percent == shownPercent_) return;
        shownPercent_ = percent;
        constexpr int kWidth = 30;
        const int filled = percent * kWidth / 100;
        const double seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
        std::fprintf(stderr, "\r%s [%s%s] %3d%% %.1fs", label_.c_str(),
                     std::string(filled, '#').c_str(), std::string(kWidth - filled, '.').c_str(),
                     percent, seconds);
        std::fflush(stderr);
    }

  private:
    std::string label_;
    bool enabled_;
    int shownPercent_ = -1;
    std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

}  // namespace distile::cli
