// Whole-file reads and writes with or without gzip, shared by the loader
// plugins (no SDK types): bounded inflation of a .gz stream, and checked
// writes of a file's parts.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace hzio {

// A gzip stream that cannot be inflated (truncated, damaged): a problem of
// the file's contents, message without the path.
struct CorruptData : std::runtime_error {
    using std::runtime_error::runtime_error;
};

// The first `limit` bytes of the gzip stream `path` inflated, or all of it
// if shorter (never more: the declared size bounds the work, and memory
// grows only as real data arrives, 16 MiB at a time, so a small file that
// declares gigabytes costs what it holds). A stream damaged within 1 MiB
// past `limit` is an error too. Throws IoError (cannot open, not a regular
// file) or CorruptData.
std::vector<unsigned char> gunzip(const std::string &path, std::uint64_t limit);

// Writes `parts` (pointer, byte count) one after another to `path`
// (created or truncated), through gzip (level 6) with `gz`, checking every
// write and the close. Throws IoError ("cannot create: ...", "write
// failed: ...") with the system's reason.
void write_parts(const std::string &path, bool gz, const std::vector<std::pair<const void *, std::uint64_t>> &parts);

}  // namespace hzio
