// Connectomes (the paper's Fig. 6): nodes as spheres sized and coloured by
// their values, edges as tubes as thick as their weights, above a threshold.
//
// Read from BrainNet Viewer's files: a `.node` file (one node a line: x y z
// (RAS+ mm), a colour value, a size value, a label; `-` for none; `#`
// starts a comment) and an `.edge` file (the N x N matrix, whitespace
// separated); or from CSV/text files of the same columns (x, y, z, then
// optionally colour and size) and a comma- or whitespace-separated matrix;
// or from a parcellation (a label volume: the labels' centroids).
#pragma once

#include <hz/core/data.hpp>

#include <array>
#include <filesystem>
#include <string>
#include <vector>

namespace hz::core::render {

struct Connectome {
    std::vector<std::array<double, 3>> xyz;  // per node, RAS+ mm
    std::vector<double> colour, size;        // per node (1 where the file gives none)
    std::vector<std::string> labels;         // per node ("" for none)
    std::vector<double> weights;             // N x N, row-major; empty: nodes only
    std::size_t nodes() const { return xyz.size(); }
};

// Reads the nodes and (unless `edge_file` is empty) the matrix; throws
// Error naming the file and the line ("a.edge: line 3: 5 values, the node
// file has 6 nodes"). At most 65536 nodes and 64 MiB a file.
Connectome read_connectome(const std::filesystem::path &node_file, const std::filesystem::path &edge_file);

// The nodes of a parcellation: one per label (a positive integer value of
// `labels`, a 3D volume read as `what`), in increasing label order, at the
// centroid of its voxels (RAS+ mm), coloured by its label value, size 1;
// and the matrix of `edge_file` (unless empty), whose rows and columns are
// the labels in that order. Throws Error for a volume that is not 3D, a
// label that is not a whole number, more than 65536 labels, none at all.
Connectome connectome_of_labels(const Volume &labels, const std::string &what, const std::filesystem::path &edge_file);

struct ConnectomeOptions {
    double threshold = 0;    // edges of |weight| above it are drawn
    double node_scale = 1;   // a node's sphere radius: its size times this (mm)
    double edge_radius = 1;  // the tube radius of the largest |weight| (mm); others in proportion
};

// The nodes as one mesh of spheres (per-vertex "node_value" array: the
// node's colour value), and the edges above the threshold as two-point
// streamlines from the first node to the second (i < j; where the matrix is
// not symmetric, the larger |weight| of the two), with per-streamline
// "weight" and "radius_mm" arrays. Throws Error for options out of range.
Mesh connectome_nodes(const Connectome &c, const ConnectomeOptions &o);
Tractogram connectome_edges(const Connectome &c, const ConnectomeOptions &o);

}  // namespace hz::core::render
