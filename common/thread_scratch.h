/// @file
/// Working memory kept per thread: the arrays of a batch's rays, hits and marches, set up once per
/// thread instead of once per call (constructing them for every call cost a few percent of a
/// render).
#pragma once

#include <type_traits>

namespace distile {

/// This thread's `T`, constructed on the thread's first call; what its last user left in it.
/// `T` is a type of the caller's own (a local struct): each type has one per thread.
/// It must be trivially destructible: a thread's first use of a thread_local with a destructor
/// registers that destructor under the dynamic loader's lock, and waits there for as long as
/// another thread loads a library (OpenImageIO's module loads beside a render to a TIFF, for
/// 0.3-0.5 s).
template <class T>
T& threadScratch() {
    static_assert(std::is_trivially_destructible_v<T>,
                  "thread scratch must be trivially destructible (see threadScratch)");
    thread_local T scratch;
    return scratch;
}

}  // namespace distile
