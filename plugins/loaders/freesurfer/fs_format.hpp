// FreeSurfer binary files: triangle surfaces and "new format" curv files.
// Format (nibabel freesurfer/io.py, FORMATS.md 1.7): big-endian; surfaces
// start FF FF FE, a "created by ..." line and a blank line, int32 vnum,
// fnum, vnum x 3 float32, fnum x 3 int32, an optional volume-info footer;
// curv files start FF FF FF, int32 vnum, fnum, values per vertex (1), then
// vnum float32.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace fsurf {

struct FormatError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

struct Surface {
    bool curv = false;                // a curv file: per-vertex values only
    std::vector<float> values;        // curv values
    std::string created;
    std::vector<float> vertices;
    std::vector<std::uint32_t> faces;
    std::vector<std::pair<std::string, std::string>> footer;  // volume info, in file order
};

std::uint32_t be32(const unsigned char *p);
// True for the first bytes of a curv file (needs 15 bytes).
bool looks_like_curv(const unsigned char *b, std::uint64_t size);
// Parses a whole file (surface or curv); throws FormatError. Counts are
// checked against `size` before anything is allocated.
Surface parse(const unsigned char *b, std::uint64_t size);

}  // namespace fsurf
