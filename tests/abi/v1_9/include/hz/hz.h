/*
 * Horizon plugin SDK: the whole C ABI in one include.
 *
 *   hz_macros.h      export / calling-convention macros, HZ_HAS_FIELD
 *   hz_version.h     ABI version, entry symbol name
 *   hz_types.h       status, errors, dtypes, array and streamline views, parameter schema
 *   hz_host.h        host services (logging, extensions) and tasks (progress, cancellation)
 *   hz_plugin.h      the exported entry table and the plugin descriptor
 *   hz_loader.h      "hz.loader/1"      file formats
 *   hz_shader.h      "hz.shader/1"      shading models
 *   hz_clustering.h  "hz.clustering/1"  streamline clustering
 *
 * The design, ownership and threading rules are in sdk/docs/ABI.md.
 */
#ifndef HZ_H
#define HZ_H

#include "hz_macros.h"
#include "hz_version.h"
#include "hz_types.h"
#include "hz_host.h"
#include "hz_plugin.h"
#include "hz_loader.h"
#include "hz_shader.h"
#include "hz_clustering.h"

#endif /* HZ_H */
