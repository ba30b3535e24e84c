#pragma once

// fsm-viewer --check-screenshot: is a PNG more than a blank background?

#include <string>

namespace fsm::examples {

/// Reads the PNG at `path` and returns the fraction of its pixels that differ from the top-left
/// one (non_background_fraction); fsm::Error naming the path when it cannot be read.
[[nodiscard]] double png_non_background_fraction(const std::string& path);

}  // namespace fsm::examples
