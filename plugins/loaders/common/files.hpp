// Files of the loader plugins (no SDK types): the companion files a data
// file names (a GIFTI ExternalFileName, a glTF buffer or image uri), where
// they may be; and whole-file writes that report every failure.
#pragma once

#include <cstddef>
#include <string>

namespace hzio {

// Resolves `name`, as written in the file at `input`, to the companion
// file's path. Accepted: a relative name that, with symbolic links resolved,
// stays inside the input's folder and is a regular file. Anything else (an
// absolute name, `..` out of the folder, a link out of it, a FIFO or device,
// which would block or read the machine's files) throws IoError with a
// one-line reason naming `name`.
std::string companion_path(const std::string &input, const std::string &name);

// The same check for a path already joined to the input's folder (by a
// library that resolves names itself, like tinygltf); returns it resolved.
std::string contained_file(const std::string &input, const std::string &path);

// Writes `bytes` bytes to `path` (created or truncated), checking every
// write and the close: a full disk or `ulimit -f` throws IoError with the
// system's reason instead of leaving a silently truncated file.
void write_file(const std::string &path, const void *data, std::size_t bytes);

}  // namespace hzio
