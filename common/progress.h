/// @file
/// Progress reporting for long work. Libraries call it on the thread that started the work,
/// with the fraction done in [0, 1]; the command line turns it into a bar (or nothing).
#pragma once

#include <functional>

namespace distile {

using ProgressCallback = std::function<void(double fractionDone)>;

}  // namespace distile
