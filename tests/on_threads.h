/// @file
/// Runs work on a given number of threads: the tests that check a result does not depend on the
/// thread count compute it on one thread and on two and compare.
#pragma once

#include <tbb/global_control.h>

#include <cstddef>
#include <utility>

namespace distile {

/// What `work()` returns, computed with TBB limited to `threads` threads.
template <class Work>
auto onThreads(int threads, Work&& work) {
    const tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                                    std::size_t(threads));
    return std::forward<Work>(work)();
}

}  // namespace distile
