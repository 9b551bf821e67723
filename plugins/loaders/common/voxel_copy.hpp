// Voxels into a strided destination, shared by the volume loaders
// (header-only; no SDK types: the destination is described by plain
// values, as hz_array_view holds them).
#pragma once

#include <cstdint>
#include <cstring>
#include <vector>

namespace hzio {

// Where voxels go: `ndim` axes of `shape` extents, `stride_bytes` apart, in
// a buffer of `capacity_bytes` at `data`.
struct StridedDest {
    void *data;
    std::uint32_t ndim;
    const std::uint64_t *shape;
    const std::int64_t *stride_bytes;
    std::uint64_t capacity_bytes;
};

enum class CopyCheck { Ok, BadAxes, BadShape, TooSmall };

// Copies the voxels of a volume of extents `dims` (x fastest) into `dst`,
// whose axes are the volume's with the trailing ones merged into its last
// (1 to 4 of them): `each(v, out)` writes voxel v (in file order) as
// `out_size` bytes at `out`, and may throw (a cancelled read). Nothing is
// written unless the destination's axes, shape and extent fit (the check
// returned otherwise).
template <class F>
CopyCheck copy_voxels(std::vector<std::uint64_t> dims, std::size_t out_size, const StridedDest &dst, F &&each) {
    if (dst.ndim < 1 || dst.ndim > 4) return CopyCheck::BadAxes;
    std::uint64_t nb = 1;
    for (std::uint64_t d : dims) nb *= d;
    while (dims.size() > dst.ndim) {
        const std::uint64_t last = dims.back();
        dims.pop_back();
        dims.back() *= last;
    }
    while (dims.size() < dst.ndim) dims.push_back(1);
    for (std::size_t i = 0; i < dims.size(); ++i)
        if (dst.shape[i] != dims[i]) return CopyCheck::BadShape;
    std::int64_t lo = 0, hi = 0;
    for (std::size_t i = 0; i < dims.size(); ++i) {
        const std::int64_t span = static_cast<std::int64_t>(dims[i] - 1) * dst.stride_bytes[i];
        (span < 0 ? lo : hi) += span;
    }
    if (lo < 0 || static_cast<std::uint64_t>(hi) + out_size > dst.capacity_bytes) return CopyCheck::TooSmall;
    auto *base = static_cast<unsigned char *>(dst.data);
    std::uint64_t idx[4] = {0, 0, 0, 0};
    for (std::uint64_t v = 0; v < nb; ++v) {
        std::int64_t off = 0;
        for (std::size_t i = 0; i < dims.size(); ++i) off += static_cast<std::int64_t>(idx[i]) * dst.stride_bytes[i];
        each(v, base + off);
        for (std::size_t i = 0; i < dims.size(); ++i) {  // x fastest (Fortran order)
            if (++idx[i] < dims[i]) break;
            idx[i] = 0;
        }
    }
    return CopyCheck::Ok;
}

}  // namespace hzio
