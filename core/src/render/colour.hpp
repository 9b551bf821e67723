// Colour and value helpers the renderer's geometry builders share (private
// to the renderer): sRGB decoding, 8-bit quantisation, packed tangents, and
// the values of named data arrays.
#pragma once

#include <hz/core/data.hpp>

#include <array>
#include <cstdint>
#include <vector>

namespace hz::core::render {

// The sRGB transfer function's inverse, c in [0, 1].
double srgb_to_linear(double c);
// A unit vector as GL_INT_2_10_10_10_REV (snorm), w = 0.
std::uint32_t pack_snorm_2_10_10_10(float x, float y, float z);
// Components in [0, 1] (clamped; NaN as 0) as 8-bit values.
std::array<std::uint8_t, 4> rgba8(double r, double g, double b, double a = 1.0);
// `count` values of type `dtype`, `stride` bytes apart, as doubles.
std::vector<double> values_of(const std::byte *data, hz_dtype dtype, std::uint64_t count, std::size_t stride);
// Values of a named array as doubles (any dtype, first component).
std::vector<double> array_values(const DataArray &a);
// The finite values' range; {0, 1} when there are none, widened by 1 when flat.
std::array<double, 2> finite_range(const std::vector<double> &v);

}  // namespace hz::core::render
