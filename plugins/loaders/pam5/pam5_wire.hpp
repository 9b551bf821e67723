// The frames between the PAM5 loader plugin (pam5_plugin.cpp) and its HDF5
// reader program (pam5_reader.cpp): a tag byte, then
//   'H' (open): X Y Z N (uint64), the affine (16 doubles, row-major), the
//       version (text), the number of header entries (uint64), each entry's
//       key and value (text);
//   'P' (read): a plane (x fixed) of Y x Z x N x 3 float32, C order, each
//       peak's unit direction times its value;
//   'E': the error's one-line message (text), the last frame.
// Text is a uint64 length and its bytes; numbers in the machine's order
// (both ends are the same build).
#pragma once

#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace pam5wire {

struct FormatError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

// What the reader sends at open: the extents, the affine, the header entries.
struct Header {
    std::uint64_t X = 0, Y = 0, Z = 0, N = 0;
    std::array<double, 16> affine{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    std::string version;
    std::vector<std::pair<std::string, std::string>> meta;
};

}  // namespace pam5wire
