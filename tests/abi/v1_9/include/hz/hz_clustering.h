/*
 * Horizon plugin SDK: the streamline clustering interface ("hz.clustering/1").
 *
 * A clusterer partitions streamlines into a tree of clusters, one level per
 * distance threshold (QuickBundlesX); a flat clustering (QuickBundles) is a
 * tree with one level below the root. The input is never copied by the
 * host; a plugin builds only what it needs (e.g. resampled features).
 *
 * Protocol: create() -> set_param()* -> run() -> get_result() ... ->
 *           [set_param()* -> run() -> get_result()]* -> destroy()
 */
#ifndef HZ_CLUSTERING_H
#define HZ_CLUSTERING_H

#include "hz_host.h"

HZ_EXTERN_C_BEGIN

/* Opaque clusterer, PLUGIN-owned from create() until destroy(). */
typedef struct hz_clusterer hz_clusterer;

/*
 * The result: a tree in which node 0 is the root (level 0, every streamline).
 * Nodes of level l (1 <= l <= nb_levels) are the clusters formed with
 * level_thresholds[l-1]. Node ids are ordered by level, then in the order the
 * algorithm lists that level's clusters (see the plugin's documentation);
 * the members of every level partition the input.
 *
 * Output struct: the CALLER zero-fills it and sets struct_size. Every
 * pointer is PLUGIN-owned and valid until the next run(), set_param() or
 * destroy() on the same clusterer; the host copies what it keeps.
 */
typedef struct hz_cluster_tree_view {
    uint32_t struct_size;
    uint32_t nb_levels;               /* levels below the root (QB: 1)                     */
    const double *level_thresholds;   /* nb_levels, in mm                                  */
    uint64_t nb_nodes;                /* including the root                                */
    const int64_t *parent;            /* nb_nodes; -1 for the root                         */
    const uint32_t *level;            /* nb_nodes; 0 for the root                          */
    uint32_t nb_points;               /* points per centroid                               */
    const float *centroids;           /* nb_nodes x nb_points x 3, RAS+ mm                 */
    const uint64_t *member_offsets;   /* nb_nodes + 1 (CSR with sentinel)                  */
    const uint64_t *members;          /* streamline indices into the input, insertion order */
} hz_cluster_tree_view;

/* The clustering interface table. PLUGIN-owned, valid until deinit(). */
typedef struct hz_clustering {
    uint32_t struct_size;
    uint32_t param_count;

    /* Parameter `index` < param_count, or NULL. PLUGIN-owned, static. [thread-safe] */
    const hz_param_info *(HZ_ABI *get_param)(uint32_t index);

    /*
     * Creates a clusterer with every parameter at its default. `host` is
     * HOST-owned and outlives the clusterer. *out is PLUGIN-owned until
     * destroy(). [thread-safe]
     */
    hz_status(HZ_ABI *create)(const hz_host *host, hz_clusterer **out, hz_error *err);

    /*
     * Sets parameter `name` to `count` values (1 for scalars; the array length
     * for FLOAT_ARRAY). HZ_E_NOT_FOUND for an unknown name,
     * HZ_E_INVALID_ARGUMENT outside the schema's range. `values` is
     * CALLER-owned, copied. [worker, not while run() is in progress]
     */
    hz_status(HZ_ABI *set_param)(hz_clusterer *c, const char *name, const double *values,
                                 uint32_t count, hz_error *err);

    /*
     * Clusters `input` (HOST-owned, valid for this call only, never copied).
     * `ordering` is NULL (process in index order) or a permutation of
     * [0, nb_streamlines) giving the processing order (HOST-owned, valid for
     * the call). The result must not depend on anything else: the same input
     * and ordering give the same result. Polls task->is_cancelled.
     * HZ_E_FORMAT for non-finite coordinates. Since 1.5, input->gap may be 1
     * (a mapped TCK): streamline s ends at offsets[s+1] - gap, and the
     * delimiter vertex after it (all NaN) is no coordinate. [worker]
     */
    hz_status(HZ_ABI *run)(hz_clusterer *c, const hz_streamlines_view *input,
                           const uint64_t *ordering, const hz_task *task, hz_error *err);

    /* Describes the last successful run() (see hz_cluster_tree_view). [worker] */
    hz_status(HZ_ABI *get_result)(const hz_clusterer *c, hz_cluster_tree_view *out,
                                  hz_error *err);

    /* Releases the clusterer; NULL is a no-op. [worker, not while run() is in progress] */
    void(HZ_ABI *destroy)(hz_clusterer *c);
} hz_clustering;

HZ_EXTERN_C_END

#endif /* HZ_CLUSTERING_H */
