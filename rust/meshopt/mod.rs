//! meshoptimizer (Kapoulkine), through the `meshopt` crate: the simplifier and the glTF
//! codecs of `EXT_meshopt_compression` / `KHR_meshopt_compression`.
//!
//! **Files**, one algorithm each as in meshoptimizer's `src/`, imports running one way
//! (`buffer_view` -> the codecs and `filter` -> `decoded`; `reorder` -> `index_codec`):
//! `simplify.rs` (edge-collapse simplification), `vertex_codec.rs` (the vertex codec),
//! `index_codec.rs` (the index and index sequence codecs, and the triangle-list check),
//! `reorder.rs` (the vertex cache and fetch order the codecs compress best), `filter.rs`
//! (the octahedral, quaternion and exponential encoders and the decoders' filters), `decoded.rs` (the aligned buffer the
//! decoders write, and their errors) and `buffer_view.rs` (one `bufferView` decoded as its
//! extension object declares).
//!
//! # Codecs
//!
//! meshoptimizer's glTF codecs (`EXT_meshopt_compression`, `KHR_meshopt_compression`): the encoders meshbits writes with (the vertex codec, the
//! index codec, the octahedral filter) and the decoders it reads with (the vertex, index
//! and index sequence codecs and the extensions' filters).
//!
//! The vertex codec encodes a stream of fixed-size records (a multiple of 4 bytes, at most
//! 256) by byte-wise deltas between consecutive records, then entropy codes them; it is
//! lossless. `EXT_meshopt_compression` decoders read its version 0 bitstream, which is
//! what [`encode_vertices`] writes. The index codec encodes a triangle list against a small
//! cache of recent edges and vertices (lossless; version 1, which the extension reads). The
//! octahedral filter stores unit vectors (normals, tangents) as two signed K-bit components
//! of the octahedral map (Cigolle et al. 2014), the decoder reconstructing the third.
//!
//! The decoders ([`decode_buffer_view`] and the functions it calls) take what a glTF
//! `bufferView`'s extension object declares (`count`, `byteStride`, `mode`, `filter`),
//! check it against the extension's rules before calling meshoptimizer's C decoders (whose
//! own checks are debug assertions), and turn every failure of a decoder on a corrupt or
//! truncated stream into a [`MeshError`](crate::MeshError). They are safe on untrusted
//! input: meshoptimizer documents them so (a corrupt stream may decode to garbage, such as
//! indices out of range, which the glTF reader checks), and no buffer is allocated before
//! the stream is long enough for what it declares.
//!
//! # Simplification
//!
//! Error-bounded, attribute-aware edge-collapse simplification: meshoptimizer's simplifier
//! (Kapoulkine, `meshopt_simplifyWithAttributes`, meshoptimizer 1.3 through the `meshopt`
//! crate), the simplifier of gltfpack.
//!
//! Collapses are ordered by a quadric error (Garland & Heckbert 1997: the squared distance
//! to the planes of the original triangles around a vertex, plus edge quadrics on borders
//! and seams, plus weighted attribute quadrics); the simplifier stops at a target
//! triangle count or, first, before the error of the next collapse would pass
//! `target_error`. Its reported error is the largest such error reached: a length in mesh
//! units here (`meshopt_SimplifyErrorAbsolute`), an estimate of the distance from the
//! original surface, not a bound on the Hausdorff distance.
//!
//! Collapses only merge a vertex into a neighbour: every output vertex is an input vertex,
//! at its input position (unless `update_positions` moves it to where its quadric is
//! least), so the output is returned as the indices of the kept input vertices and faces
//! over them. Vertices that share a position but differ in index are an
//! attribute seam (UV or normal discontinuity): the simplifier keeps the seam's shape and
//! collapses along it only. A geometry-only mesh should therefore arrive welded.

mod buffer_view;
mod decoded;
mod filter;
mod index_codec;
mod reorder;
mod simplify;
mod vertex_codec;

#[cfg(test)]
mod tests;

pub use buffer_view::{Mode, decode_buffer_view};
pub use decoded::Decoded;
pub use filter::{
    ExponentMode, Filter, decode_filter, encode_exponential, encode_octahedral, encode_quaternions,
};
pub use index_codec::{decode_index_sequence, decode_triangles, encode_triangles};
pub use reorder::reorder_for_codecs;
pub use simplify::{Attributes, MAX_ATTRIBUTES, Request, Simplified, simplify};
pub use vertex_codec::{decode_vertices, encode_vertices};
