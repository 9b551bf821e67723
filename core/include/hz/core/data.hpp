// The data model shared by every Horizon subsystem (I/O, clustering,
// rendering): tractograms, triangle meshes and volumes, in RAS+ millimetres.
#pragma once

#include <hz/hz.h>

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <type_traits>
#include <memory>
#include <mutex>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace hz::core {

// A runtime error whose message is one line, ready to print ("tck: a.tck: ...").
struct Error : std::runtime_error {
    using std::runtime_error::runtime_error;
};

// The memory the kernel reports can be had without swapping (MemAvailable
// in /proc/meminfo), in bytes; SIZE_MAX when unknown.
// HORIZON_MEMORY_AVAILABLE_MB overrides it (tests).
std::size_t memory_available();
// A size for messages: "640 MB", "2.1 GB".
std::string gb(double bytes);

// `bytes` of uninitialised memory aligned to 64 bytes; throws std::bad_alloc.
std::shared_ptr<void> allocate_uninitialised(std::size_t bytes);

// For large decoded arrays (a TRK's positions: 2 GB at a million
// streamlines): from `kSpillBytes` up, the memory is a shared mapping of an
// unlinked temporary file in the spill folder ($HORIZON_SPILL_DIR, default
// /var/tmp; "off" disables), so its pages are the page cache's: written back
// and reclaimed under memory pressure instead of held as the process's
// anonymous memory, as a mapped input file's are. Smaller arrays, or no
// usable folder (absent, full, no O_TMPFILE): allocate_uninitialised, if
// the kernel reports that much memory available (MemAvailable); otherwise
// throws Error, one line: the size, why no temporary file holds it, the
// memory available. Zero-filled where file-backed. HORIZON_SPILL_MIN_BYTES
// overrides kSpillBytes and HORIZON_MEMORY_AVAILABLE_MB the memory
// available (tests). Throws std::bad_alloc.
inline constexpr std::size_t kSpillBytes = std::size_t(256) << 20;
std::shared_ptr<void> allocate_spillable(std::size_t bytes);

// An array that is not zero-filled on creation (decoders overwrite it), so
// that reading 1 GB of positions does not first write 1 GB of zeros. A Buffer
// may also view memory owned by someone else (a file mapping the host made
// for a zero-copy read): `owner` keeps it alive. Or it may be deferred: its
// elements are written by a `fill` function into fresh memory on the first
// access to them (data(), begin(), operator[], span()), once, whichever
// thread gets there first (std::call_once), and shared with every
// shared() view. The host defers the copy of positions a file stores at an
// offset float32 may not be read at (a TCK written by nibabel): whoever
// needs them as floats pays for the copy; `horizon info` does not.
// Move-only.
template <class T>
class Buffer {
    static_assert(std::is_trivially_copyable_v<T>);

public:
    // What fills a deferred buffer: writes all size() elements to dst.
    // Called at most once; released (with what it holds) after the call.
    using Fill = std::function<void(T *dst)>;

    Buffer() = default;
    explicit Buffer(std::size_t n) : size_(n) {
        if (n == 0) return;
        std::shared_ptr<void> block = allocate_uninitialised(n * sizeof(T));
        ptr_ = static_cast<T *>(block.get());
        owner_ = std::move(block);
    }
    Buffer(std::initializer_list<T> init) : Buffer(init.size()) { std::copy(init.begin(), init.end(), ptr_); }
    // A new array holding a copy of `values`.
    static Buffer copy_of(std::span<const T> values) {
        Buffer b(values.size());
        std::copy(values.begin(), values.end(), b.ptr_);
        return b;
    }
    // `n` elements written by `fill` on first access (see above).
    static Buffer deferred(std::size_t n, Fill fill) {
        Buffer b;
        if (n == 0) return b;
        b.size_ = n;
        b.deferred_ = std::make_shared<Deferred>();
        b.deferred_->fill = std::move(fill);
        return b;
    }
    // A view of `n` elements at `p`, alive as long as `owner`.
    Buffer(T *p, std::size_t n, std::shared_ptr<void> owner) : ptr_(n ? p : nullptr), size_(n), owner_(std::move(owner)) {}
    Buffer(const Buffer &) = delete;
    Buffer &operator=(const Buffer &) = delete;
    Buffer(Buffer &&o) noexcept
        : ptr_(std::exchange(o.ptr_, nullptr)),
          size_(std::exchange(o.size_, 0)),
          owner_(std::move(o.owner_)),
          deferred_(std::move(o.deferred_)) {}
    Buffer &operator=(Buffer &&o) noexcept {
        if (this != &o) {
            ptr_ = std::exchange(o.ptr_, nullptr);
            size_ = std::exchange(o.size_, 0);
            owner_ = std::move(o.owner_);
            deferred_ = std::move(o.deferred_);
        }
        return *this;
    }
    T *data() { return ptr_ ? ptr_ : resolve(); }
    const T *data() const { return ptr_ ? ptr_ : resolve(); }
    std::size_t size() const { return size_; }
    bool empty() const { return size_ == 0; }
    T &operator[](std::size_t i) { return data()[i]; }
    const T &operator[](std::size_t i) const { return data()[i]; }
    T *begin() { return data(); }
    T *end() { return data() + size_; }
    const T *begin() const { return data(); }
    const T *end() const { return data() + size_; }
    std::span<const T> span() const { return {data(), size_}; }
    // Another view of the same elements, keeping them alive (a deferred
    // buffer's views share its one fill).
    Buffer shared() const {
        Buffer b(ptr_, size_, owner_);
        b.deferred_ = deferred_;
        return b;
    }
    // Whether the elements are still to be written (a deferred buffer not
    // yet accessed).
    bool pending() const { return deferred_ != nullptr && !deferred_->done.load(std::memory_order_acquire); }

private:
    struct Deferred {
        std::once_flag once;
        Fill fill;
        std::shared_ptr<void> block;
        T *ptr = nullptr;
        std::atomic<bool> done{false};
    };
    T *resolve() const {
        if (!deferred_) return nullptr;
        Deferred &d = *deferred_;
        std::call_once(d.once, [&d, n = size_] {
            std::shared_ptr<void> block = allocate_uninitialised(n * sizeof(T));
            d.fill(static_cast<T *>(block.get()));
            d.ptr = static_cast<T *>(block.get());
            d.block = std::move(block);
            d.fill = nullptr;  // (drops what it held: the file mapping)
            d.done.store(true, std::memory_order_release);
        });
        return d.ptr;
    }

    T *ptr_ = nullptr;
    std::size_t size_ = 0;
    std::shared_ptr<void> owner_;
    std::shared_ptr<Deferred> deferred_;
};

// Axis-aligned bounds in RAS+ mm of a set of xyz triples (NaN coordinates skipped); empty -> all zero.
struct Bounds {
    std::array<double, 3> min{}, max{};
    bool empty = true;
};
Bounds bounds_of(const float *xyz, std::uint64_t nb_points);
// Grows `a` to hold `b`.
void merge_bounds(Bounds &a, const Bounds &b);
// Checks that the nb_points xyz triples at `xyz` are finite and returns their
// bounds, in one pass, on up to two threads per core pair (std::thread) when
// there are millions. Throws Error "`what`: non-finite coordinate at vertex
// K" (K counted from `first_vertex`) for the first such vertex.
Bounds finite_bounds(const float *xyz, std::uint64_t nb_points, const std::string &what, std::uint64_t first_vertex = 0);
// The same for streamlines with one delimiter vertex after each (a mapped
// TCK): streamline s is xyz[offsets[s] .. offsets[s+1] - 1) and vertex
// offsets[s+1] - 1 must be all NaN; every other coordinate must be finite.
// offsets (N + 1 entries, non-decreasing, offsets[N] = nb_points) are
// checked first. Throws Error naming `what`.
Bounds delimited_bounds(const float *xyz, std::uint64_t nb_points, const std::uint64_t *offsets, std::uint64_t N, const std::string &what);
// Runs fn(begin, end) over [0, n) split into contiguous ranges of at least
// `grain` items, one per thread (the calling thread takes the first); the
// first exception thrown by the lowest range is rethrown.
void parallel_ranges(std::uint64_t n, std::uint64_t grain, const std::function<void(std::uint64_t, std::uint64_t)> &fn);

// Row-major 4x4 affine.
using Affine = std::array<double, 16>;
constexpr Affine kIdentity = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};

std::size_t dtype_size(hz_dtype t);
// The element of type `t` at `p` (any alignment), as a double (NaN for an unknown type).
double value_at(const std::byte *p, hz_dtype t);
const char *dtype_name(hz_dtype t);

// Extra per-vertex / per-streamline / per-face data.
struct DataArray {
    std::string name;
    hz_attach attach = HZ_ATTACH_VERTEX;
    hz_dtype dtype = HZ_DTYPE_F32;
    std::uint32_t components = 1;
    std::uint64_t count = 0;
    Buffer<std::byte> bytes;  // count x components x dtype_size, C order
};

// A one-component float32 array of `values`.
DataArray f32_array(std::string name, hz_attach attach, const std::vector<float> &values);

// Streamlines: positions (float32 xyz, RAS+ mm) + offsets (N + 1, sentinel).
// Streamline s is positions[offsets[s] .. offsets[s+1] - gap): `gap`
// vertices after each streamline belong to none. gap is 0, except for an
// MRtrix TCK file mapped without a copy (gap 1: its NaN delimiter triples
// stay in place). A tractogram with a gap has no per-vertex arrays.
struct Tractogram {
    Buffer<float> positions;
    Buffer<std::uint64_t> offsets{0};
    std::uint32_t gap = 0;
    std::vector<DataArray> arrays;
    Affine reference = kIdentity;  // reference grid voxel -> RAS+ mm
    std::array<std::uint64_t, 3> reference_dims{};

    std::uint64_t nb_streamlines() const { return offsets.empty() ? 0 : offsets.size() - 1; }
    // The streamlines' vertices (delimiters not counted).
    std::uint64_t nb_vertices() const { return nb_stored() - std::uint64_t(gap) * nb_streamlines(); }
    // The vertices `positions` holds, delimiters included.
    std::uint64_t nb_stored() const { return positions.size() / 3; }
    // Streamline s: vertices [begin(s), end(s)) of positions.
    std::uint64_t begin(std::uint64_t s) const { return offsets[s]; }
    std::uint64_t end(std::uint64_t s) const { return offsets[s + 1] - gap; }
    std::uint64_t size(std::uint64_t s) const { return end(s) - begin(s); }
    // The ABI view, gap included (a plugin that does not offer
    // HZ_EXT_DELIMITED_STREAMLINES must be given the view of compacted()
    // instead: it would ignore the gap; LoadedPlugin::streamlines_for).
    hz_streamlines_view view() const;
    // A shallow copy: the same buffers (positions, offsets, arrays), kept alive.
    Tractogram shared() const;
    // The same streamlines without delimiters: a copy when gap != 0,
    // otherwise shared().
    Tractogram compacted() const;
    // Checks the invariants (offsets start at 0, non-decreasing, sentinel,
    // finite positions); throws Error naming `what`. Returns the bounds of
    // the positions (computed in the same pass).
    Bounds validate(const std::string &what) const;
    // The offsets part of validate() alone.
    void validate_offsets(const std::string &what) const;
};

// The streamlines `ids` of `t`, in that order (positions only; indices < N).
// With `spill`, a large selection's positions are allocate_spillable's (a
// selection kept for display, e.g. a region's streamlines out of ten
// million: page cache rather than the process's anonymous memory; Error
// when it fits neither a temporary file nor the memory available). Once
// `cancel` (when given) is set, the copy stops early: what is returned then
// is to be discarded.
Tractogram select_streamlines(const Tractogram &t, const std::vector<std::uint64_t> &ids, bool spill = false,
                              const std::atomic<bool> *cancel = nullptr);

// Triangle mesh, RAS+ mm.
struct Mesh {
    Buffer<float> vertices;       // nb x 3
    Buffer<std::uint32_t> faces;  // nb x 3, 0-based
    std::vector<DataArray> arrays;
    Affine transform = kIdentity;  // the format's own matrix (GIFTI DataSpace -> TransformedSpace), kept for writing
    std::uint64_t nb_vertices() const { return vertices.size() / 3; }
    std::uint64_t nb_faces() const { return faces.size() / 3; }
};

// Volume with a voxel-to-RAS+ affine; x varies fastest.
struct Volume {
    hz_dtype dtype = HZ_DTYPE_F32;
    std::vector<std::uint64_t> dims;
    Buffer<std::byte> voxels;
    double scale_slope = 1.0, scale_inter = 0.0;
    Affine voxel_to_ras = kIdentity;
};

// One file's content, whatever its kind.
struct Dataset {
    hz_data_kind kind = 0;
    std::string format;     // "tck Float32LE"
    std::string loader_id;  // plugin that read it
    hz_space source_space = HZ_SPACE_UNKNOWN;
    std::vector<std::pair<std::string, std::string>> metadata;
    Tractogram tractogram;
    Mesh mesh;
    Volume volume;
    // Bounds of the streamline positions or mesh vertices as read (empty for
    // volumes and overlays); read_dataset fills it during validation.
    Bounds bounds;
    // True when the positions view a copy-on-write mapping of the file (a
    // zero-copy read) rather than a decoded copy.
    bool mapped = false;
    // True when they were mapped at an offset float32 cannot be read at (a
    // TCK written by nibabel): the floats are copied to aligned memory when
    // first used (Buffer::deferred).
    bool unaligned = false;
};

// A per-vertex overlay without geometry (a FreeSurfer curv file, an
// overlay-only GIFTI): a mesh dataset with no vertices, no faces and
// per-vertex arrays, all of one count.
bool is_overlay(const Dataset &ds);
// The vertex count an overlay describes (0 if `ds` is not one).
std::uint64_t overlay_vertices(const Dataset &ds);
// Appends the per-vertex arrays of `overlay` to `mesh` (a name already taken
// gets " (2)", " (3)", ...). Throws Error naming `what` when the overlay's
// vertex count is not the mesh's. Returns the names as added.
std::vector<std::string> attach_overlay(Mesh &mesh, const Dataset &overlay, const std::string &what);

const char *kind_name(hz_data_kind k);
const char *space_name(hz_space s);

}  // namespace hz::core
