// FreeSurfer MGH/MGZ volumes (no SDK types): the 284-byte big-endian header,
// the voxels (x fastest, then y, z, frames), the optional footer of scan
// parameters; read from a memory-mapped .mgh or an inflated .mgz, and
// written. The voxel-to-RAS affine follows FreeSurfer (and nibabel): the
// direction cosines scaled by the voxel sizes, placed so that voxel
// dims / 2 lands on the header's centre c_ras.
#pragma once

#include "mapped_file.hpp"

#include <array>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace mgh {

// A file that is not a valid MGH volume; message without the path.
struct FormatError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

// The voxel types MGH stores (its type codes: 0, 4, 1, 3).
enum class DType { U8, I16, I32, F32 };
std::size_t dtype_size(DType t);

constexpr std::uint64_t kDataOffset = 284;

struct Header {
    std::array<std::int64_t, 4> dims{};  // width, height, depth, frames
    DType dtype = DType::U8;
    int type_code = 0;
    int dof = 0;
    bool good_ras = false;                 // false: FreeSurfer's default orientation (LIA, 1 mm, centre 0)
    std::array<double, 3> delta{1, 1, 1};  // voxel sizes, mm
    std::array<double, 9> mdc{};           // direction cosines of x, y, z (3 each, RAS)
    std::array<double, 3> c_ras{};         // RAS of voxel dims / 2
    std::uint64_t nb_voxels = 0, data_bytes = 0;
    // Footer (zero when absent): repetition time and echo times in ms, flip angle in radians, field of view.
    double tr = 0, flip_angle = 0, te = 0, ti = 0, fov = 0;
    bool has_footer = false;
    std::array<double, 16> affine() const;  // voxel index -> RAS+ mm, row-major
};

// Confidence in [0, 100] that `head` starts an MGH file (version 1, a known
// type, positive sizes); a gzip stream with a name ending in .mgz: 60.
int probe(const unsigned char *head, std::uint64_t size, const char *name_hint);

// An open volume: header, and its voxels (big-endian) in place.
class Volume {
public:
    // Reads `path` (.mgz / .mgh.gz: inflated within the declared size;
    // else mapped). Throws FormatError or hzio::IoError / hzio::CorruptData.
    static Volume open(const std::string &path);
    const Header &header() const { return h_; }
    const unsigned char *voxels() const { return data_; }
    bool gz() const { return gz_; }

private:
    Header h_;
    bool gz_ = false;
    std::vector<unsigned char> inflated_;
    std::shared_ptr<hzio::MappedFile> mapped_;
    const unsigned char *data_ = nullptr;
};

// Writes a volume of `dims` (1 to 4 axes, x fastest) of `dtype` from
// `voxels` (native byte order, contiguous) with voxel-to-RAS `affine`
// (row-major) and the scan parameters, gzipped with `gz`. Throws FormatError
// (sizes MGH cannot hold, an affine without three independent axes) or
// hzio::IoError.
void write(const std::string &path, bool gz, DType dtype, const std::vector<std::uint64_t> &dims, const void *voxels,
           const std::array<double, 16> &affine, double tr, double flip_angle, double te, double ti, double fov);

}  // namespace mgh
