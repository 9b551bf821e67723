// hz.loader/1 for the MRtrix TCK format: tck::Loader (tck_loader.hpp)
// through the SDK's C++ loader adapter, which writes the C table, its
// extensions and the descriptor's interface list.
#include "tck_loader.hpp"

namespace {

const hz_plugin_descriptor kDescriptor = {
    .struct_size = sizeof(hz_plugin_descriptor),
    .abi = HZ_ABI_VERSION_INIT,
    .kind = HZ_KIND_LOADER,
    .id = "org.horizon.loader.tck",
    .name = "MRtrix TCK",
    .version = "1.0.0",
    .vendor = "Horizon",
    .description = "MRtrix3 .tck streamlines: Float32/Float64, both byte orders, read and write",
    .license = "MIT",
    .interfaces = hz::loader<tck::Loader>::interfaces,
};

using Plugin = hz::loader_plugin<kDescriptor, tck::Loader>;

}  // namespace

void tck::log_warning(const std::string &message) { hz::log(Plugin::host(), kDescriptor.id, HZ_LOG_WARN, message); }

HZ_DECLARE_PLUGIN_ENTRY = Plugin::entry;
