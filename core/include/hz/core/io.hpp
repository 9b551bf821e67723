// Reading and writing datasets through loader plugins.
//
// Loader selection follows OpenImageIO's ImageInput::create: the loader whose
// extension matches the file name (longest suffix wins) is used when its
// probe() confirms the first bytes (score >= 50) or when no other loader
// claims them; otherwise every loader probes and the highest score wins.
// Writers are chosen by extension only.
#pragma once

#include <hz/core/data.hpp>
#include <hz/core/plugin_host.hpp>

#include <string>
#include <vector>

namespace hz::core {

// Lower-case extension of `path` that `loader` claims ("nii.gz"), or "".
std::string matching_extension(const hz_loader &loader, const fs::path &path);

// Picks the loader for reading `path`; throws Error naming the file.
const LoadedPlugin &loader_for_read(const Registry &reg, const fs::path &path);
// Picks the writer for `path` by extension (the longest claimed suffix);
// with `kind` set, writers that hold that kind of data come first (.hdr is a
// NIfTI header for volumes and a Radiance picture for images). Throws Error
// naming the file.
const LoadedPlugin &loader_for_write(const Registry &reg, const fs::path &path, hz_data_kind kind = 0);

// The hz_array_view of a volume's voxels (contiguous, x fastest; axes beyond
// 4 merged into the last).
hz_array_view volume_view(const Volume &v);

// Reads a whole file into the data model. Throws Error with a one-line message.
// Bounds a reader must respect before it allocates (0: none): the pixels of
// an image (width x height) and what to call it in the error.
struct ReadLimits {
    std::uint64_t max_pixels = 0;
    const char *what = "image";
};
Dataset read_dataset(const Registry &reg, const fs::path &path, const hz_task *task = nullptr, const ReadLimits &limits = {});
// The host's own pass over a dataset's streamlines (Tractogram::validate:
// every coordinate finite, delimiters all NaN), whose bounds must be the
// `reported` ones (what the loader vouched for); throws Error naming `path`
// and `loader` otherwise. A deferred copy of the positions is made first.
void check_reported_bounds(const Tractogram &t, const Bounds &reported, const fs::path &path, const std::string &loader);

// The whole of a small text file a command reads (a scene, an ordering):
// only a regular file (a FIFO is refused instead of blocking, /dev/zero
// instead of being read for ever), of at most `max_bytes` (checked before
// reading and while reading: a file that grows is not read past the
// bound). `what` names it in errors: "FILE: WHAT larger than N MiB".
// Throws Error.
std::string read_small_file(const fs::path &file, std::uint64_t max_bytes, const std::string &what);

// Makes every page of [p, p + bytes) resident and mapped now, on both
// cores, in a few calls (MADV_POPULATE_READ) instead of a page fault per 16
// pages as they are first read: for a consumer about to read all of a mapped
// file's positions (a TCK read in place), so that mapping them is part of
// reading it. Memory that is already resident costs a walk of its pages.
// Nothing is written; where the kernel cannot (before Linux 5.14) the pages
// fault in as before.
void make_resident(const void *p, std::size_t bytes);

// ------------------------------------------------------------------ outputs
// Every output is written to a temporary file beside it (.NAME.tmp-PID-N),
// synced, then renamed into place (output.cpp).

// Removes the temporaries being written when the process gets SIGINT,
// SIGTERM or SIGHUP (then dies of the signal as before); ignores SIGXFSZ (a
// write past `ulimit -f` then fails with EFBIG and is reported); turns the
// SIGBUS of a mapped input truncated while read into one error line naming
// the file (found in /proc/self/maps) and exit status 1.
// Called once, early, by the program.
void install_termination_cleanup();

// A temporary output: removed (file or directory) on destruction unless
// published, and by the termination handler meanwhile. Not copyable.
class TemporaryFile {
public:
    explicit TemporaryFile(const fs::path &path);
    ~TemporaryFile();
    TemporaryFile(const TemporaryFile &) = delete;
    TemporaryFile &operator=(const TemporaryFile &) = delete;
    const fs::path &path() const { return path_; }
    void published() { published_ = true; }

private:
    fs::path path_;
    int slot_ = -1;
    bool published_ = false;
};

// A new temporary's path for output `path`, beside it: .NAME.tmp-PID-RANDOM,
// NAME cut (at a character boundary) so that the name stays within
// NAME_MAX (255 bytes) however long `path`'s own name is (a 250-byte name
// used to fail for its temporary's). remove_stale_temporaries knows it.
fs::path temporary_path(const fs::path &path);

// Throws Error if `path` exists and is not a regular file or a symbolic
// link: a device, FIFO or socket is never replaced (renaming over /dev/null
// as root would replace the device), a directory never overwritten.
void check_output_target(const fs::path &path);

// Removes temporaries of `path` (.NAME.tmp-PID...) left by processes that
// are gone (killed, power cut).
void remove_stale_temporaries(const fs::path &path);

// Syncs `tmp`, renames it to `path` and syncs the directory. Without
// `force` an existing `path` is never replaced, atomically (of two writers
// of the same new output, one fails). Throws Error naming `path`, with the
// system's reason; `tmp` is then removed by its destructor.
void publish(TemporaryFile &tmp, const fs::path &path, bool force);

// Publishes several files that make one output (a NIfTI .hdr/.img pair) as
// a unit: all of them, or none. With `force`, the files they replace are
// first renamed aside (.NAME.old-PID-RANDOM, in the same folder) and only
// removed once every new file is in place; when one fails, the new files
// already placed are removed and the old ones renamed back, and the error
// names the file that failed. (A process killed in between leaves the old
// files under those names: hidden, never deleted.)
void publish_together(const std::vector<std::pair<TemporaryFile *, fs::path>> &files, bool force);

// Writes `text` to `path` through a temporary file in the same directory,
// renamed over `path` on success and deleted on failure. Refuses to replace
// an existing file unless `force`. Throws Error naming `path`.
void write_text_atomic(const fs::path &path, const std::string &text, bool force);

// Writes `ds` to `path` atomically: into a temporary file in the same
// directory, renamed over `path` on success, deleted on failure. Refuses to
// overwrite an existing file unless `force`, and never overwrites `protect`
// (the input). Parts the format cannot hold are appended to `dropped`.
// With `selection` (strictly increasing indices of ds.tractogram's
// streamlines), the file holds those streamlines with their arrays, as if
// subset_with_arrays had copied them out first; a writer offering
// hz.ext.write-selection/1 reads them where they lie instead.
void write_dataset(const Registry &reg, const Dataset &ds, const fs::path &path, bool force, std::vector<std::string> *dropped,
                   const fs::path &protect = {}, const hz_task *task = nullptr, const std::vector<std::uint64_t> *selection = nullptr);

}  // namespace hz::core
