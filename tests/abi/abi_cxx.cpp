/* Compiles the SDK headers as strict C++ and checks HZ_HAS_FIELD at run time. */
#include "abi_layout.h"

int main(void) {
    hz_dataset_info info{};
    info.struct_size = (uint32_t)offsetof(hz_dataset_info, nb_arrays); /* an older, shorter struct */
    if (HZ_HAS_FIELD(&info, hz_dataset_info, nb_arrays)) return 1;
    if (!HZ_HAS_FIELD(&info, hz_dataset_info, source_space)) return 2;
    if (sizeof(HZ_PLUGIN_ENTRY_SYMBOL) != sizeof("hz_plugin_entry_v1")) return 3;
    return 0;
}
