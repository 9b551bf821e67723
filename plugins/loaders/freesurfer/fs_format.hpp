// FreeSurfer binary files: triangle surfaces and "new format" curv files.
// Format (nibabel freesurfer/io.py, FORMATS.md 1.7): big-endian; surfaces
// start FF FF FE, a "created by ..." line and a blank line, int32 vnum,
// fnum, vnum x 3 float32, fnum x 3 int32, an optional volume-info footer;
// curv files start FF FF FF, int32 vnum, fnum, values per vertex (1), then
// vnum float32; quad surfaces start FF FF FF or FF FF FD (read only).
#pragma once

#include "label_table.hpp"

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
    bool curv = false;          // a curv file: per-vertex values only
    bool quad = false;          // read from a quad surface (faces: each quad split in two)
    std::vector<float> values;  // curv values
    std::string created;
    std::vector<float> vertices;
    std::vector<std::uint32_t> faces;
    std::vector<std::pair<std::string, std::string>> footer;  // volume info, in file order
};

// An annotation (lh.aparc.annot): a label per vertex and its colour table.
// Format (nibabel freesurfer/io.py read_annot; FreeSurfer's colortab.c):
// big-endian int32 vnum, vnum (vertex, value) pairs where value packs the
// label's colour as r + g*256 + b*65536 (0: no label); int32 1 (a colour
// table follows); then either the old table (int32 n > 0, int32 length +
// original-table path, n x {int32 length + name, int32 r g b t}) or
// version 2 (int32 -2, int32 max index, int32 length + path, int32 count,
// count x {int32 index, int32 length + name, int32 r g b t}).
using AnnotEntry = hzlabel::Entry;  // index, name, r g b t (t: transparency)
struct Annotation {
    // Per vertex: the colour-table index of its label, -1 without one (a
    // value of 0, or a colour no entry has).
    std::vector<std::int32_t> labels;
    std::vector<AnnotEntry> table;  // in file order
    std::string orig_table;
};
// Parses a whole .annot file; throws FormatError. Every count is checked
// against the bytes left before anything is allocated.
Annotation parse_annot(const unsigned char *b, std::uint64_t size);

std::uint32_t be32(const unsigned char *p);
// True for the first bytes of a curv file (needs 15 bytes).
bool looks_like_curv(const unsigned char *b, std::uint64_t size);
// True for a quad surface (FF FF FD, or FF FF FF laid out as a quad file
// rather than a curv file); needs 9 bytes and the whole file's size.
bool is_quad(const unsigned char *b, std::uint64_t size);
// Parses a whole file (triangle or quad surface, or curv); throws FormatError. Counts are
// checked against `size` before anything is allocated.
Surface parse(const unsigned char *b, std::uint64_t size);

}  // namespace fsurf
