// GIFTI surfaces and overlays (GIFTI 1.0; ../shared/formats/FORMATS.md 1.6):
// XML through pugixml; ASCII, Base64Binary, GZipBase64Binary (zlib) and
// ExternalFileBinary encodings; both endians; row- and column-major.
// Pure C++ without SDK types; gifti_plugin.cpp adapts it to hz.loader/1.
#pragma once

#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace gifti {

struct FormatError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

// A per-vertex data array other than the geometry (shape, label, func...).
struct Overlay {
    std::string name;  // its Name meta value, else its intent
    std::string intent;
    bool integer = false;  // integer data (labels, read as int32) vs FLOAT32/FLOAT64
    std::uint32_t components = 1;
    std::vector<float> values;         // FLOAT32 data, vertices x components
    std::vector<double> values64;      // FLOAT64 data instead, when not empty (read and written as such)
    std::vector<std::int32_t> labels;  // integer data
};

// One entry of the file's LabelTable: a label key and its colour (0..1).
struct Label {
    std::int32_t key = 0;
    std::string name;
    double red = 0, green = 0, blue = 0, alpha = 1;
    bool coloured = true;  // false: no Red, Green, Blue or Alpha attribute (written without them)
};

struct Surface {
    std::vector<float> vertices;         // N x 3, as stored (mm in DataSpace)
    std::vector<std::uint32_t> faces;    // M x 3, 0-based
    std::array<double, 16> transform{};  // DataSpace -> TransformedSpace, identity if absent
    std::string data_space, transformed_space;
    std::vector<Overlay> overlays;
    std::vector<std::pair<std::string, std::string>> metadata;
    std::vector<Label> labels;  // the LabelTable (keys of the NIFTI_INTENT_LABEL arrays)
    std::uint64_t rows = 0;     // vertices the overlays describe (= vertices / 3 unless overlay-only)
    bool overlay_only() const { return vertices.empty() && faces.empty() && !overlays.empty(); }
};

// Reads and validates a whole .gii file (faces in range, sizes = Dims).
Surface read(const std::string &path);

// Writes GZipBase64Binary (gz) or Base64Binary arrays, little-endian,
// row-major: POINTSET, TRIANGLE, then float overlays as NIFTI_INTENT_SHAPE
// (or their intent) and integer ones as NIFTI_INTENT_LABEL, with `s.labels`
// as the LabelTable (an overlay-only file when `s` has no geometry).
void write(const std::string &path, const Surface &s, bool gz);

int probe(const unsigned char *head, std::uint64_t size);

}  // namespace gifti
