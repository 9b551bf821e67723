// GIFTI 1.0 (GIFTI file format specification; nibabel's parse_gifti_fast.py
// for the accepted aliases). XML by pugixml, deflate by zlib.
#include "gifti_format.hpp"

#include "files.hpp"
#include "mapped_file.hpp"

#include <pugixml.hpp>
#include <zlib.h>

#include <algorithm>
#include <bit>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <tuple>

namespace gifti {

namespace fs = std::filesystem;

namespace {

enum class DT { U8, I8, I16, U16, I32, U32, F32, F64 };

std::size_t dt_size(DT t) {
    switch (t) {
    case DT::U8:
    case DT::I8: return 1;
    case DT::I16:
    case DT::U16: return 2;
    case DT::I32:
    case DT::U32:
    case DT::F32: return 4;
    case DT::F64: return 8;
    }
    return 0;
}

DT parse_dtype(const std::string &s) {
    static const std::pair<const char *, DT> m[] = {
        {"NIFTI_TYPE_UINT8", DT::U8},  {"NIFTI_TYPE_INT8", DT::I8},    {"NIFTI_TYPE_INT16", DT::I16},   {"NIFTI_TYPE_UINT16", DT::U16},
        {"NIFTI_TYPE_INT32", DT::I32}, {"NIFTI_TYPE_UINT32", DT::U32}, {"NIFTI_TYPE_FLOAT32", DT::F32}, {"NIFTI_TYPE_FLOAT64", DT::F64}};
    for (const auto &[n, d] : m)
        if (s == n) return d;
    throw FormatError("DataType '" + s + "' is not a supported NIfTI type");
}

// RFC 4648 base64, whitespace tolerated (line breaks are common).
std::vector<unsigned char> base64_decode(const char *s, std::size_t n) {
    static const auto table = [] {
        std::array<int, 256> t{};
        t.fill(-1);
        const char *a = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
        for (int i = 0; i < 64; ++i) t[static_cast<unsigned char>(a[i])] = i;
        return t;
    }();
    std::vector<unsigned char> out;
    out.reserve(n / 4 * 3);
    std::uint32_t acc = 0;
    int bits = 0, pad = 0;
    for (std::size_t i = 0; i < n; ++i) {
        const unsigned char c = static_cast<unsigned char>(s[i]);
        if (c == ' ' || c == '\n' || c == '\r' || c == '\t') continue;
        if (c == '=') {
            ++pad;
            continue;
        }
        if (pad || table[c] < 0) throw FormatError("invalid base64 character at offset " + std::to_string(i) + " of a <Data> element");
        acc = (acc << 6) | static_cast<std::uint32_t>(table[c]);
        bits += 6;
        if (bits >= 8) {
            bits -= 8;
            out.push_back(static_cast<unsigned char>((acc >> bits) & 0xFF));
        }
    }
    if (pad > 2) throw FormatError("invalid base64 padding in a <Data> element");
    return out;
}

std::string base64_encode(const unsigned char *p, std::size_t n) {
    static const char *a = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    out.reserve((n + 2) / 3 * 4);
    for (std::size_t i = 0; i < n; i += 3) {
        const std::uint32_t v = (std::uint32_t(p[i]) << 16) | (i + 1 < n ? std::uint32_t(p[i + 1]) << 8 : 0) | (i + 2 < n ? p[i + 2] : 0);
        out.push_back(a[(v >> 18) & 63]);
        out.push_back(a[(v >> 12) & 63]);
        out.push_back(i + 1 < n ? a[(v >> 6) & 63] : '=');
        out.push_back(i + 2 < n ? a[v & 63] : '=');
    }
    return out;
}

double load(const unsigned char *p, DT t, bool swap) {
    unsigned char b[8];
    const std::size_t n = dt_size(t);
    std::memcpy(b, p, n);
    if (swap) std::reverse(b, b + n);
    switch (t) {
    case DT::U8: return b[0];
    case DT::I8: return static_cast<std::int8_t>(b[0]);
    case DT::I16: {
        std::int16_t v;
        std::memcpy(&v, b, 2);
        return v;
    }
    case DT::U16: {
        std::uint16_t v;
        std::memcpy(&v, b, 2);
        return v;
    }
    case DT::I32: {
        std::int32_t v;
        std::memcpy(&v, b, 4);
        return v;
    }
    case DT::U32: {
        std::uint32_t v;
        std::memcpy(&v, b, 4);
        return v;
    }
    case DT::F32: {
        float v;
        std::memcpy(&v, b, 4);
        return v;
    }
    case DT::F64: {
        double v;
        std::memcpy(&v, b, 8);
        return v;
    }
    }
    return 0;
}

struct Array {
    std::string intent, name;
    DT dtype;
    std::uint64_t rows = 0, cols = 1;
    std::vector<double> values;  // rows x cols, row-major
    std::array<double, 16> transform{};
    bool has_transform = false;
    std::string data_space, transformed_space;
};

// A value for a message, without converting out-of-range doubles to integers.
std::string fmt_number(double x) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.17g", x);
    return buf;
}

Array read_array(const pugi::xml_node &da, std::size_t index, const fs::path &dir) {
    Array a;
    const std::string at = "DataArray " + std::to_string(index);
    a.intent = da.attribute("Intent").as_string();
    a.dtype = parse_dtype(da.attribute("DataType").as_string());
    const std::string order = da.attribute("ArrayIndexingOrder").as_string("RowMajorOrder");
    const bool col_major = order == "ColumnMajorOrder";
    if (!col_major && order != "RowMajorOrder") throw FormatError(at + ": ArrayIndexingOrder '" + order + "'");
    const int ndim = da.attribute("Dimensionality").as_int(1);
    if (ndim < 1 || ndim > 2) throw FormatError(at + ": Dimensionality " + std::to_string(ndim) + " is not 1 or 2");
    auto dim = [&](int k) {
        const std::string key = "Dim" + std::to_string(k);
        const pugi::xml_attribute d = da.attribute(key.c_str());
        const long long v = d.as_llong(-1);
        if (!d || v < 1 || v > (1ll << 31)) throw FormatError(at + ": " + key + " is missing or not in 1..2^31");
        return static_cast<std::uint64_t>(v);
    };
    a.rows = dim(0);
    a.cols = ndim == 2 ? dim(1) : 1;
    const std::uint64_t n = a.rows * a.cols;  // each <= 2^31: no overflow
    const std::size_t es = dt_size(a.dtype);
    if (n > (std::uint64_t(1) << 40) / std::max<std::size_t>(es, 1)) throw FormatError(at + ": Dims declare more than 2^40 bytes");
    std::string enc = da.attribute("Encoding").as_string();
    if (enc == "GIFTI_ENCODING_ASCII") enc = "ASCII";
    if (enc == "GIFTI_ENCODING_B64BIN") enc = "Base64Binary";
    if (enc == "GIFTI_ENCODING_B64GZ") enc = "GZipBase64Binary";
    if (enc == "GIFTI_ENCODING_EXTBIN") enc = "ExternalFileBinary";
    std::string endian = da.attribute("Endian").as_string("LittleEndian");
    if (endian == "GIFTI_ENDIAN_LITTLE") endian = "LittleEndian";
    if (endian == "GIFTI_ENDIAN_BIG") endian = "BigEndian";
    if (endian != "LittleEndian" && endian != "BigEndian") throw FormatError(at + ": Endian '" + endian + "'");
    const bool swap = (endian == "BigEndian") != (std::endian::native == std::endian::big);
    for (const auto &md : da.child("MetaData").children("MD"))
        if (std::string(md.child_value("Name")) == "Name") a.name = md.child_value("Value");
    if (const pugi::xml_node m = da.child("CoordinateSystemTransformMatrix")) {
        std::istringstream in(m.child_value("MatrixData"));
        for (int i = 0; i < 16; ++i)
            if (!(in >> a.transform[static_cast<std::size_t>(i)])) throw FormatError(at + ": MatrixData does not hold 16 numbers");
        a.has_transform = true;
        a.data_space = m.child_value("DataSpace");
        a.transformed_space = m.child_value("TransformedSpace");
    }
    // Every size is checked against what the file holds before anything of
    // size n is allocated (a few bytes must not ask for gigabytes).
    const char *text = da.child_value("Data");
    const std::size_t text_len = std::strlen(text);
    std::vector<double> raw;
    if (enc == "ASCII") {
        if (n > text_len / 2 + 1)
            throw FormatError(at + ": Dims require " + std::to_string(n) + " numbers; the ASCII data has room for at most " +
                              std::to_string(text_len / 2 + 1));
        raw.resize(n);
        const char *p = text;
        for (std::uint64_t i = 0; i < n; ++i) {
            char *end = nullptr;
            raw[i] = std::strtod(p, &end);
            if (end == p) throw FormatError(at + ": ASCII data holds " + std::to_string(i) + " numbers, Dims require " + std::to_string(n));
            p = end;
        }
    } else {
        std::vector<unsigned char> bytes;
        if (enc == "Base64Binary" || enc == "GZipBase64Binary") {
            bytes = base64_decode(text, text_len);
            if (enc == "GZipBase64Binary") {
                // zlib expands at most 1032:1.
                if (n * es > 1032 * std::uint64_t(bytes.size()) + 64)
                    throw FormatError(at + ": Dims declare " + std::to_string(n * es) + " bytes; " + std::to_string(bytes.size()) +
                                      " compressed bytes cannot hold them");
                std::vector<unsigned char> out(n * es);
                uLongf len = static_cast<uLongf>(out.size());
                const int rc = uncompress(out.data(), &len, bytes.data(), static_cast<uLong>(bytes.size()));
                if (rc == Z_BUF_ERROR) throw FormatError(at + ": compressed data is larger than Dims declare");
                if (rc != Z_OK)
                    throw FormatError(
                        at + ": GZipBase64Binary payload is not a valid zlib (RFC 1950) stream" +
                        std::string(bytes.size() > 1 && bytes[0] == 0x1f && bytes[1] == 0x8b ? " (it is a gzip container)" : ""));
                out.resize(len);
                bytes.swap(out);
            }
        } else if (enc == "ExternalFileBinary") {
            const std::string name = da.attribute("ExternalFileName").as_string();
            const long long off = da.attribute("ExternalFileOffset").as_llong(0);
            if (name.empty() || off < 0) throw FormatError(at + ": ExternalFileBinary without a file name or with a negative offset");
            fs::path ext;
            try {
                ext = hzio::companion_path((dir / "x").string(), name);
            } catch (const hzio::IoError &e) {
                throw FormatError(at + ": " + e.what());
            }
            std::error_code ec;
            const std::uint64_t size = fs::file_size(ext, ec);
            if (ec) throw FormatError(at + ": external file " + ext.string() + " cannot be opened");
            if (std::uint64_t(off) > size || n * es > size - std::uint64_t(off))
                throw FormatError(at + ": external file " + ext.string() + " holds " + std::to_string(size) + " bytes, Dims require " +
                                  std::to_string(n * es) + " from offset " + std::to_string(off));
            std::ifstream in(ext, std::ios::binary);
            if (!in) throw FormatError(at + ": external file " + ext.string() + " cannot be opened");
            in.seekg(off);
            bytes.resize(n * es);
            in.read(reinterpret_cast<char *>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
            bytes.resize(static_cast<std::size_t>(std::max<std::streamsize>(in.gcount(), 0)));
        } else {
            throw FormatError(at + ": Encoding '" + enc + "' is not supported");
        }
        if (bytes.size() != n * es)
            throw FormatError(at + ": decoded " + std::to_string(bytes.size()) + " bytes, Dims and DataType require " +
                              std::to_string(n * es));
        raw.resize(n);
        for (std::uint64_t i = 0; i < n; ++i) raw[i] = load(bytes.data() + i * es, a.dtype, swap);
    }
    // Binary data stored column by column is transposed to rows. ASCII text is
    // read row by row whatever the order says, as nibabel reads (and writes) it.
    if (col_major && a.cols > 1 && enc != "ASCII") {
        a.values.resize(n);
        for (std::uint64_t r = 0; r < a.rows; ++r)
            for (std::uint64_t c = 0; c < a.cols; ++c) a.values[r * a.cols + c] = raw[c * a.rows + r];
    } else {
        a.values = std::move(raw);
    }
    return a;
}

}  // namespace

int probe(const unsigned char *head, std::uint64_t size) {
    const std::string s(reinterpret_cast<const char *>(head), static_cast<std::size_t>(std::min<std::uint64_t>(size, 4096)));
    if (s.find("<GIFTI") != std::string::npos) return 95;
    if (s.rfind("<?xml", 0) == 0 && s.find("gifti", 0) != std::string::npos) return 60;
    return 0;
}

Surface read(const std::string &path) {
    hzio::MappedFile file(path);
    pugi::xml_document doc;
    const pugi::xml_parse_result res = doc.load_buffer(file.data(), file.size());
    if (!res) throw FormatError(std::string("XML error at byte ") + std::to_string(res.offset) + ": " + res.description());
    const pugi::xml_node root = doc.child("GIFTI");
    if (!root) throw FormatError("no <GIFTI> root element");
    Surface s;
    s.transform = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    for (const auto &md : root.child("MetaData").children("MD")) s.metadata.emplace_back(md.child_value("Name"), md.child_value("Value"));
    for (const auto &lab : root.child("LabelTable").children("Label")) {
        Label l;
        // "Index" is GIFTI's earlier name for "Key" (nibabel's label.gii)
        const std::string key = lab.attribute("Key") ? lab.attribute("Key").as_string() : lab.attribute("Index").as_string();
        char *end = nullptr;
        const long long k = std::strtoll(key.c_str(), &end, 10);
        if (key.empty() || *end != '\0' || k < INT32_MIN || k > INT32_MAX)
            throw FormatError("LabelTable entry " + std::to_string(s.labels.size()) + ": Key '" + key + "' is not an int32");
        l.key = static_cast<std::int32_t>(k);
        l.name = lab.child_value();
        // A label with none of the colour attributes (nibabel writes none for
        // a label it has no colour for) has no colour: it is drawn in one
        // generated from its key (label_table.hpp) and written back without
        // them. One with some of them takes 0 for a missing Red, Green or
        // Blue and 1 for Alpha. Components are clamped to [0, 1].
        l.coloured = lab.attribute("Red") || lab.attribute("Green") || lab.attribute("Blue") || lab.attribute("Alpha");
        for (auto [attr, dst, def] :
             {std::tuple{"Red", &l.red, 0.0}, {"Green", &l.green, 0.0}, {"Blue", &l.blue, 0.0}, {"Alpha", &l.alpha, 1.0}}) {
            const pugi::xml_attribute a = lab.attribute(attr);
            if (!a) {
                *dst = def;
                continue;
            }
            const std::string text = a.as_string();
            const double x = std::strtod(text.c_str(), &end);
            if (text.empty() || *end != '\0' || !std::isfinite(x))
                throw FormatError("LabelTable entry " + std::to_string(s.labels.size()) + ": " + attr + " '" + text + "' is not a number");
            *dst = std::clamp(x, 0.0, 1.0);
        }
        s.labels.push_back(std::move(l));
    }
    std::vector<Array> arrays;
    std::size_t i = 0;
    for (const auto &da : root.children("DataArray")) arrays.push_back(read_array(da, i++, fs::path(path).parent_path()));
    const Array *points = nullptr, *tris = nullptr;
    for (const auto &a : arrays) {
        if (a.intent == "NIFTI_INTENT_POINTSET" && !points)
            points = &a;
        else if (a.intent == "NIFTI_INTENT_TRIANGLE" && !tris)
            tris = &a;
    }
    if (arrays.empty()) throw FormatError("no DataArray at all");
    // An overlay-only file (thickness, curvature, labels of a surface kept
    // elsewhere): per-vertex arrays that all have the first array's rows.
    auto add_overlay = [&](const Array &a) {
        Overlay o;
        o.intent = a.intent;
        o.name = a.name.empty() ? a.intent : a.name;
        o.components = static_cast<std::uint32_t>(a.cols);
        o.integer = a.dtype != DT::F32 && a.dtype != DT::F64;
        if (o.integer) {
            // Integer arrays (labels) are kept as int32; a value outside it
            // (an ASCII array can hold any number) is an error, not a wrap.
            o.labels.reserve(a.values.size());
            for (const double x : a.values) {
                if (!(x >= -2147483648.0 && x <= 2147483647.0) || x != std::floor(x))
                    throw FormatError("integer array '" + o.name + "' holds " + fmt_number(x) + ", not an int32 value");
                o.labels.push_back(static_cast<std::int32_t>(x));
            }
        } else if (a.dtype == DT::F64) {
            o.values64 = a.values;  // kept as float64, not narrowed
        } else {
            o.values.assign(a.values.begin(), a.values.end());
        }
        s.overlays.push_back(std::move(o));
    };
    if (!points) {
        if (tris) throw FormatError("a NIFTI_INTENT_TRIANGLE array without a NIFTI_INTENT_POINTSET");
        s.rows = arrays.front().rows;
        if (s.rows == 0) throw FormatError("overlay-only file whose first array has no rows");
        for (const auto &a : arrays) {
            if (a.rows != s.rows)
                throw FormatError("overlay-only file with arrays of " + std::to_string(s.rows) + " and " + std::to_string(a.rows) +
                                  " rows: not one surface's vertices");
            add_overlay(a);
        }
        return s;
    }
    if (!tris) throw FormatError("no NIFTI_INTENT_TRIANGLE array (a point cloud, not a mesh)");
    if (points->cols != 3) throw FormatError("POINTSET has " + std::to_string(points->cols) + " columns, expected 3");
    if (tris->cols != 3) throw FormatError("TRIANGLE has " + std::to_string(tris->cols) + " columns, expected 3");
    const std::uint64_t nv = points->rows;
    s.vertices.resize(points->values.size());
    for (std::size_t k = 0; k < s.vertices.size(); ++k) {
        s.vertices[k] = static_cast<float>(points->values[k]);
        if (!std::isfinite(s.vertices[k])) throw FormatError("vertex " + std::to_string(k / 3) + " has a non-finite coordinate");
    }
    s.faces.resize(tris->values.size());
    for (std::size_t k = 0; k < s.faces.size(); ++k) {
        const double f = tris->values[k];
        if (!(f >= 0 && f < double(nv)) || f != std::floor(f))
            throw FormatError("triangle " + std::to_string(k / 3) + " uses vertex " + fmt_number(f) + ", outside [0, " +
                              std::to_string(nv) + ")");
        s.faces[k] = static_cast<std::uint32_t>(f);
    }
    if (points->has_transform) {
        s.transform = points->transform;
        s.data_space = points->data_space;
        s.transformed_space = points->transformed_space;
    }
    s.rows = nv;
    for (const auto &a : arrays) {
        if (&a == points || &a == tris) continue;
        if (a.rows != nv) continue;  // not per vertex (e.g. a second surface): not an overlay of this mesh
        add_overlay(a);
    }
    return s;
}

void write(const std::string &path, const Surface &s, bool gz) {
    pugi::xml_document doc;
    auto decl = doc.prepend_child(pugi::node_declaration);
    decl.append_attribute("version") = "1.0";
    decl.append_attribute("encoding") = "UTF-8";
    pugi::xml_node root = doc.append_child("GIFTI");
    root.append_attribute("Version") = "1.0";
    const bool geometry = !s.overlay_only();
    root.append_attribute("NumberOfDataArrays") = static_cast<unsigned>((geometry ? 2 : 0) + s.overlays.size());
    pugi::xml_node meta = root.append_child("MetaData");
    for (const auto &[k, v] : s.metadata) {
        pugi::xml_node md = meta.append_child("MD");
        md.append_child("Name").append_child(pugi::node_cdata).set_value(k.c_str());
        md.append_child("Value").append_child(pugi::node_cdata).set_value(v.c_str());
    }
    pugi::xml_node table = root.append_child("LabelTable");
    for (const Label &l : s.labels) {
        pugi::xml_node lab = table.append_child("Label");
        lab.append_attribute("Key") = l.key;
        for (auto [attr, x] : {std::pair{"Red", l.red}, {"Green", l.green}, {"Blue", l.blue}, {"Alpha", l.alpha}}) {
            if (!l.coloured) break;
            char buf[32];
            std::snprintf(buf, sizeof buf, "%.9g", x);
            lab.append_attribute(attr) = buf;
        }
        lab.append_child(pugi::node_cdata).set_value(l.name.c_str());
    }
    auto add = [&](const char *intent, const char *dtype, std::uint64_t rows, std::uint64_t cols, const void *data, std::size_t es,
                   const std::string &name, bool xform) {
        pugi::xml_node da = root.append_child("DataArray");
        da.append_attribute("Intent") = intent;
        da.append_attribute("DataType") = dtype;
        da.append_attribute("ArrayIndexingOrder") = "RowMajorOrder";
        da.append_attribute("Dimensionality") = cols > 1 ? 2 : 1;
        da.append_attribute("Dim0") = static_cast<unsigned long long>(rows);
        if (cols > 1) da.append_attribute("Dim1") = static_cast<unsigned long long>(cols);
        da.append_attribute("Encoding") = gz ? "GZipBase64Binary" : "Base64Binary";
        da.append_attribute("Endian") = "LittleEndian";
        da.append_attribute("ExternalFileName") = "";
        da.append_attribute("ExternalFileOffset") = "";
        pugi::xml_node md = da.append_child("MetaData");
        if (!name.empty()) {
            pugi::xml_node e = md.append_child("MD");
            e.append_child("Name").append_child(pugi::node_cdata).set_value("Name");
            e.append_child("Value").append_child(pugi::node_cdata).set_value(name.c_str());
        }
        if (xform) {
            pugi::xml_node m = da.append_child("CoordinateSystemTransformMatrix");
            m.append_child("DataSpace")
                .append_child(pugi::node_cdata)
                .set_value(s.data_space.empty() ? "NIFTI_XFORM_SCANNER_ANAT" : s.data_space.c_str());
            m.append_child("TransformedSpace")
                .append_child(pugi::node_cdata)
                .set_value(s.transformed_space.empty() ? "NIFTI_XFORM_SCANNER_ANAT" : s.transformed_space.c_str());
            std::ostringstream out;
            out.precision(17);
            for (int r = 0; r < 4; ++r) {
                for (int c = 0; c < 4; ++c) out << s.transform[static_cast<std::size_t>(4 * r + c)] << (c < 3 ? " " : "\n");
            }
            m.append_child("MatrixData").text().set(out.str().c_str());
        }
        const std::size_t bytes = rows * cols * es;
        std::string payload;
        if (gz) {
            std::vector<unsigned char> z(compressBound(static_cast<uLong>(bytes)));
            uLongf zl = static_cast<uLongf>(z.size());
            if (compress2(z.data(), &zl, static_cast<const Bytef *>(data), static_cast<uLong>(bytes), 6) != Z_OK)
                throw FormatError("zlib compression failed");
            payload = base64_encode(z.data(), zl);
        } else {
            payload = base64_encode(static_cast<const unsigned char *>(data), bytes);
        }
        da.append_child("Data").text().set(payload.c_str());
    };
    static_assert(std::endian::native == std::endian::little, "the GIFTI writer assumes a little-endian host");
    if (geometry) {
        add("NIFTI_INTENT_POINTSET", "NIFTI_TYPE_FLOAT32", s.vertices.size() / 3, 3, s.vertices.data(), 4, "", true);
        std::vector<std::int32_t> f(s.faces.begin(), s.faces.end());
        add("NIFTI_INTENT_TRIANGLE", "NIFTI_TYPE_INT32", s.faces.size() / 3, 3, f.data(), 4, "", false);
    }
    for (const auto &o : s.overlays) {
        const std::uint64_t rows = geometry ? s.vertices.size() / 3 : s.rows;
        if (o.integer) {
            add("NIFTI_INTENT_LABEL", "NIFTI_TYPE_INT32", rows, o.components, o.labels.data(), 4, o.name, false);
        } else if (!o.values64.empty()) {
            add(o.intent.empty() ? "NIFTI_INTENT_SHAPE" : o.intent.c_str(), "NIFTI_TYPE_FLOAT64", rows, o.components, o.values64.data(), 8,
                o.name, false);
        } else {
            add(o.intent.empty() ? "NIFTI_INTENT_SHAPE" : o.intent.c_str(), "NIFTI_TYPE_FLOAT32", rows, o.components, o.values.data(), 4,
                o.name, false);
        }
    }
    if (!doc.save_file(path.c_str(), "  ", pugi::format_default, pugi::encoding_utf8)) throw FormatError("cannot write the file");
}

}  // namespace gifti
