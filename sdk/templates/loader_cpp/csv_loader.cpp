// Template loader plugin in C++, on the SDK's loader adapter
// (hz/cpp/loader.hpp): streamlines as CSV, one point per row.
//
//   streamline,x,y,z        the header
//   0,1.5,2,3               streamline 0's points, in order, RAS+ mm
//   0,1.5,2.5,3
//   1                       streamline 1, empty (an id alone)
//   2,-4,0.5,12
//
// Ids start at 0 and each new one is the next. The class below says what
// the format is; hz::loader<Csv>::table is the C table, with every argument
// check, capacity check and error message the ABI asks for written once in
// the SDK. (The C template, ../loader/text_loader.c, writes them by hand.)
#include <hz/cpp/loader.hpp>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

constexpr const char *kId = "org.example.loader.csv-streamlines";
constexpr char kHeader[] = "streamline,x,y,z";
const char *const kExtensions[] = {"csv", nullptr};

struct Csv {
    static constexpr const char *prefix = "csv";  // error messages: "csv: <file>: <what>"
    static constexpr hz_data_kind kinds = HZ_DATA_STREAMLINES;
    static constexpr uint32_t probe_bytes = 32;
    static constexpr const char *const *extensions = kExtensions;
    // Thrown below; the adapter turns them into HZ_E_FORMAT, HZ_E_IO and HZ_E_CANCELLED.
    struct FormatError : std::runtime_error {
        using std::runtime_error::runtime_error;
    };
    struct IoError : std::runtime_error {
        using std::runtime_error::runtime_error;
    };
    struct Cancelled {};

    // The whole file, parsed at open (the format is text).
    struct Reader {
        std::vector<float> positions;
        std::vector<uint64_t> offsets{0};
    };

    // Pure: only the bytes given.
    static int32_t probe(const uint8_t *head, uint64_t size, const char *) noexcept {
        const std::size_t n = sizeof kHeader - 1;
        return size > n && std::memcmp(head, kHeader, n) == 0 && (head[n] == '\n' || head[n] == '\r') ? 90 : 0;
    }

    static std::unique_ptr<Reader> open(const std::string &path, const hz_task *task) {
        std::ifstream in(path, std::ios::binary);
        if (!in) throw IoError(std::strerror(errno));
        std::string line;
        if (!std::getline(in, line) || line.rfind(kHeader, 0) != 0) throw FormatError("no 'streamline,x,y,z' header");
        auto r = std::make_unique<Reader>();
        long long current = -1;
        for (uint64_t row = 2; std::getline(in, line); ++row) {
            if ((row & 0xFFFF) == 0 && hz::cancelled(task)) throw Cancelled{};
            if (!line.empty() && line.back() == '\r') line.pop_back();
            if (line.empty()) continue;
            std::istringstream ss(line);
            long long id = -1;
            char comma = 0;
            float p[3];
            const std::string where = "row " + std::to_string(row);
            if (!(ss >> id)) throw FormatError(where + ": no streamline id");
            const bool point = bool(ss >> comma);
            if (point && !(comma == ',' && ss >> p[0] >> comma && comma == ',' && ss >> p[1] >> comma && comma == ',' && ss >> p[2]))
                throw FormatError(where + " is not 'streamline,x,y,z'");
            if (point && !(std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2])))
                throw FormatError(where + ": a coordinate is not finite");
            if (id != current) {
                if (id != current + 1)
                    throw FormatError(where + ": streamline " + std::to_string(id) + " after " + std::to_string(current));
                if (current >= 0) r->offsets.push_back(r->positions.size() / 3);
                current = id;
            }
            if (point) r->positions.insert(r->positions.end(), p, p + 3);
        }
        if (in.bad()) throw IoError(std::strerror(errno));
        if (current >= 0) r->offsets.push_back(r->positions.size() / 3);
        return r;
    }

    // The description the host allocates from (`out` comes zero-filled).
    static void info(const Reader &r, hz_dataset_info &out) {
        out.kind = HZ_DATA_STREAMLINES;
        std::snprintf(out.format, sizeof out.format, "csv streamlines");
        out.nb_streamlines = r.offsets.size() - 1;
        out.nb_vertices = r.positions.size() / 3;
        for (int i = 0; i < 4; ++i) out.voxel_to_ras[i * 5] = 1;  // no reference grid: identity
        out.source_space = HZ_SPACE_RASMM;
    }

    // Called only with destinations of the described size.
    static void read_streamlines(Reader &r, float *positions, uint64_t *offsets, const hz_task *) {
        if (!r.positions.empty()) std::memcpy(positions, r.positions.data(), r.positions.size() * sizeof(float));
        std::memcpy(offsets, r.offsets.data(), r.offsets.size() * sizeof(uint64_t));
    }

    // Positions and offsets only: every other array is reported as dropped.
    static void write(const hz_write_request &req, const hz_dataset_view &data, const hz_task *task) {
        for (uint32_t i = 0; i < data.nb_arrays && req.on_dropped != nullptr; ++i)
            req.on_dropped(req.ctx,
                           ("array '" + std::string(data.arrays[i].name ? data.arrays[i].name : "") + "' (CSV keeps points only)").c_str());
        const hz_streamlines_view &s = data.streamlines;  // (gap 0: this plugin does not offer HZ_EXT_DELIMITED_STREAMLINES)
        std::FILE *f = std::fopen(req.path, "wb");
        if (f == nullptr) throw IoError(std::strerror(errno));
        std::fprintf(f, "%s\n", kHeader);
        for (uint64_t k = 0; k < s.nb_streamlines; ++k) {
            if ((k & 0xFFF) == 0 && hz::cancelled(task)) {
                std::fclose(f);
                throw Cancelled{};
            }
            if (s.offsets[k + 1] == s.offsets[k]) std::fprintf(f, "%llu\n", (unsigned long long)k);
            for (uint64_t v = s.offsets[k]; v < s.offsets[k + 1]; ++v)
                std::fprintf(f, "%llu,%.9g,%.9g,%.9g\n", (unsigned long long)k, s.positions[3 * v], s.positions[3 * v + 1],
                             s.positions[3 * v + 2]);
        }
        if (std::ferror(f) | std::fclose(f)) throw IoError("write error");
    }
};

// The descriptor. Its interfaces, hz::loader<Csv>::interfaces, name the
// core table and the extensions (hz_extensions.h) the adapter serves for
// this class: here open() with a task (the host shows the parse's progress
// and can cancel it). A class with read_streamlines_checked, locate_positions
// and read_offsets, max_gap or write_selection gets those extensions too
// (see hz/cpp/loader.hpp; the TRK loader is a full example).
const hz_plugin_descriptor kDescriptor = {
    .struct_size = sizeof(hz_plugin_descriptor),
    .abi = HZ_ABI_VERSION_INIT,
    .kind = HZ_KIND_LOADER,
    .id = kId,
    .name = "CSV streamlines (C++ template)",
    .version = "1.0.0",
    .vendor = "Example Vendor",
    .description = "Streamlines as CSV rows 'streamline,x,y,z': a starting point for loaders in C++",
    .license = "MIT",
    .interfaces = hz::loader<Csv>::interfaces,
};

}  // namespace

HZ_DECLARE_PLUGIN_ENTRY = hz::loader_plugin<kDescriptor, Csv>::entry;
