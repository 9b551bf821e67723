// libFuzzer target: glTF 2.0 (.gltf JSON or .glb) through tinygltf and the
// plugin's own checks (accessor bounds, node hierarchy, instancing limits),
// through a file in /dev/shm.
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <unistd.h>

long long hz_gltf_fuzz_parse(const std::string &path);

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
    const bool glb = size >= 4 && std::memcmp(data, "glTF", 4) == 0;
    static const std::string base = "/dev/shm/hz_fuzz_gltf_" + std::to_string(::getpid());
    const std::string path = base + (glb ? ".glb" : ".gltf");
    if (std::FILE *f = std::fopen(path.c_str(), "wb")) {
        std::fwrite(data, 1, size, f);
        std::fclose(f);
    }
    hz_gltf_fuzz_parse(path);
    return 0;
}
