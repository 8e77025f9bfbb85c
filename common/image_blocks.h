/// @file
/// An image's pixels worked on in parallel square blocks, with progress reports that never make
/// the threads wait for each other.
#pragma once

#include <tbb/blocked_range2d.h>
#include <tbb/parallel_for.h>

#include <atomic>
#include <cstdint>
#include <thread>

#include "common/progress.h"

namespace distile {

/// Calls `body(block)` for blocks (tbb::blocked_range2d<int>: rows, then columns) of at most
/// `blockPixels` x `blockPixels` covering `width` x `height` pixels, in parallel. With
/// `progress`, the share of pixels done, mapped onto [from, to], is reported by the calling
/// thread as it finishes blocks of its own, and `to` once all are done.
template <class Body>
void forEachImageBlock(int width, int height, int blockPixels, const ProgressCallback& progress,
                       double from, double to, const Body& body) {
    const double pixels = double(width) * double(height);
    std::atomic<std::int64_t> pixelsDone{0};
    const std::thread::id caller = std::this_thread::get_id();
    tbb::parallel_for(
        tbb::blocked_range2d<int>(0, height, blockPixels, 0, width, blockPixels),
        [&](const tbb::blocked_range2d<int>& block) {
            body(block);
            if (!progress) return;
            const std::int64_t size = std::int64_t(block.rows().size()) * block.cols().size();
            const std::int64_t done = pixelsDone.fetch_add(size, std::memory_order_relaxed) + size;
            if (std::this_thread::get_id() == caller)
                progress(from + (to - from) * double(done) / pixels);
        },
        // Blocks of the size asked for: the automatic partitioner hands out larger ranges, and
        // the calling thread then reported (and Python's Ctrl-C was seen) a second apart.
        tbb::simple_partitioner());
    if (progress) progress(to);
}

}  // namespace distile
