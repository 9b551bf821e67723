/*
 * Layout locks for the 1.x ABI on LP64 (x86-64, AArch64): a field that moves
 * or changes size breaks every plugin built before, so each is pinned here.
 * Included from a C and a C++ translation unit.
 */
#include <hz/hz.h>
#include <stddef.h>

#ifdef __cplusplus
#define HZ_SA static_assert
#else
#define HZ_SA _Static_assert
#endif

HZ_SA(sizeof(hz_abi_version) == 12, "hz_abi_version");
HZ_SA(sizeof(hz_error) == 8 + HZ_ERROR_MESSAGE_SIZE, "hz_error");
HZ_SA(offsetof(hz_error, message) == 8, "hz_error.message");
HZ_SA(sizeof(hz_plugin_entry) == HZ_PLUGIN_ENTRY_MIN_SIZE, "hz_plugin_entry 1.0 size");
HZ_SA(offsetof(hz_plugin_entry, init) == 16, "entry.init");
HZ_SA(offsetof(hz_plugin_entry, get_interface) == 48, "entry.get_interface");
HZ_SA(offsetof(hz_plugin_descriptor, id) == 24, "descriptor.id");
HZ_SA(sizeof(hz_plugin_descriptor) == 80, "hz_plugin_descriptor");
HZ_SA(sizeof(hz_host) == 56, "hz_host");
HZ_SA(sizeof(hz_task) == 32, "hz_task");
HZ_SA(sizeof(hz_array_view) == 96, "hz_array_view");
HZ_SA(sizeof(hz_streamlines_view) == 40, "hz_streamlines_view");
HZ_SA(sizeof(hz_param_info) == 176, "hz_param_info");
HZ_SA(offsetof(hz_param_info, min_value) == 56, "param.min_value");
HZ_SA(sizeof(hz_dataset_info) == 312, "hz_dataset_info");
HZ_SA(offsetof(hz_dataset_info, voxel_to_ras) == 152, "info.voxel_to_ras");
HZ_SA(offsetof(hz_loader, write) == 104, "loader.write (1.0 layout)");
#if defined(__GNUC__) || defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"
#endif
HZ_SA(offsetof(hz_loader, locate_positions) == 112, "loader.locate_positions (1.4-1.9's place, back in 1.12 for source compatibility)");
HZ_SA(sizeof(hz_loader) == 120, "hz_loader (1.12: the 1.0 table and the deprecated locate_positions)");
HZ_SA(offsetof(hz_streamlines_dst, reserved0) == 4, "streamlines_dst.reserved0");
HZ_SA(offsetof(hz_streamlines_dst, check) == 40, "streamlines_dst.check (1.7-1.9's place, back in 1.12 for source compatibility)");
HZ_SA(sizeof(hz_streamlines_dst) == 48, "hz_streamlines_dst (1.12: the 1.0 struct and the deprecated check)");
#if defined(__GNUC__) || defined(__clang__)
#pragma GCC diagnostic pop
#endif
/* Extension tables (hz_extensions.h, since 1.10). */
HZ_SA(sizeof(hz_positions_check) == 56, "hz_positions_check");
HZ_SA(offsetof(hz_positions_extent, offset) == 16, "positions_extent.offset");
HZ_SA(offsetof(hz_positions_extent, accepts) == 28, "positions_extent.accepts");
HZ_SA(offsetof(hz_positions_extent, bounds_min) == 32, "positions_extent.bounds_min");
HZ_SA(sizeof(hz_positions_extent) == 80, "hz_positions_extent");
HZ_SA(offsetof(hz_ext_mapped_positions, locate_positions) == 8, "ext_mapped_positions.locate_positions");
HZ_SA(sizeof(hz_ext_mapped_positions) == 24, "hz_ext_mapped_positions");
HZ_SA(sizeof(hz_ext_checked_read) == 16, "hz_ext_checked_read");
HZ_SA(sizeof(hz_ext_delimited_streamlines) == 8, "hz_ext_delimited_streamlines");
HZ_SA(sizeof(hz_shade_point) == 136, "hz_shade_point");
HZ_SA(offsetof(hz_shader, eval_reference) == 48, "shader.eval_reference (1.0 layout)");
HZ_SA(offsetof(hz_shader, display) == 72, "shader.display (1.12, appended)");
HZ_SA(sizeof(hz_shader) == 80, "hz_shader (1.12)");
HZ_SA(sizeof(hz_cluster_tree_view) == 72, "hz_cluster_tree_view");
HZ_SA(sizeof(hz_clustering) == 56, "hz_clustering");
HZ_SA(offsetof(hz_dataset_view, metadata) == 352, "dataset_view.metadata (1.0 layout)");
HZ_SA(sizeof(hz_dataset_view) == 448, "hz_dataset_view (1.1)");
HZ_SA(offsetof(hz_write_request, ctx) == 32, "write_request.ctx (1.0 layout)");
HZ_SA(offsetof(hz_write_request, final_path) == 40, "write_request.final_path (1.3)");
HZ_SA(sizeof(hz_write_request) == 64, "hz_write_request");
