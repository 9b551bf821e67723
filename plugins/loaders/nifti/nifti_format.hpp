// NIfTI-1 and NIfTI-2 volumes: .nii, .nii.gz, .hdr/.img pairs (also gzipped).
// Pure C++ without SDK types; nifti_plugin.cpp adapts it to hz.loader/1.
// Spec facts: nifti1.h / nifti2.h as summarised in ../shared/formats/FORMATS.md
// sections 1.1-1.2; affine precedence as nibabel's get_best_affine.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace nifti {

struct FormatError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

enum class DType { U8, I8, U16, I16, U32, I32, U64, I64, F32, F64, RGB24, RGBA32 };
std::size_t dtype_size(DType t);

struct Header {
    int version = 1;    // 1 or 2
    bool swap = false;  // header and data byte order differ from the host's
    int ndim = 0;
    std::array<std::int64_t, 7> dims{};
    DType dtype = DType::U8;
    std::int16_t datatype_code = 0;
    std::array<double, 8> pixdim{};
    std::uint64_t vox_offset = 0;
    double scl_slope = 1, scl_inter = 0;  // already resolved: (1, 0) when no scaling
    int qform_code = 0, sform_code = 0;
    std::array<double, 16> affine{};  // voxel -> RAS+ mm (row-major)
    std::string affine_source;        // "sform", "qform" or "base"
    std::uint64_t nb_voxels = 0;      // product of dims
    std::string data_path;            // the file holding the voxels
    bool data_gz = false;
    std::vector<std::string> warnings;
};

// An opened image: header + access to the voxel bytes (mapped or inflated).
class Image {
public:
    static Image open(const std::string &path);  // throws FormatError
    Image(Image &&) noexcept;
    ~Image();
    const Header &header() const { return h_; }
    // Raw voxel bytes in file order and byte order: nb_voxels * dtype_size.
    const unsigned char *data() const;

private:
    Image();
    struct Impl;
    std::unique_ptr<Impl> impl_;
    Header h_;
};

// Writes a single-file NIfTI-1 (.nii, or gzipped when `gz`), little-endian,
// sform_code 1 = the affine, qform from the affine when it is a rotation.
// Writes a single-file NIfTI-1 (.nii, "n+1") to `path`, or, when
// `image_path` is not empty, a header-only .hdr ("ni1") to `path` and the
// voxels to `image_path`; `gz` compresses every file written.
void write(const std::string &path, const std::string &image_path, bool gz, DType dtype, const std::vector<std::uint64_t> &dims,
           const void *voxels, const std::array<double, 16> &affine, double slope, double inter);

int probe(const unsigned char *head, std::uint64_t size);

}  // namespace nifti
