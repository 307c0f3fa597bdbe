//! Meshes: the plain data every kind writes, and heightfield meshing.
//!
//! Units are metres with Y up; front faces wind counter-clockwise (see [`Mesh`]).

mod crowded;
mod deviation;
mod gpu_order;
mod grid_levels;
mod grid_tiles;
mod heightfield_mesh;
pub mod intersections;
mod isosurface;
mod lod;
mod normals;
mod rtin;
mod smooth;
mod types;

pub use deviation::{max_deviation, max_deviation_from, SurfaceIndex};
pub use gpu_order::GpuOrder;
pub use grid_levels::grid_levels;
pub use grid_tiles::{border_drift, grid_patch, tile_edges, with_skirt, without_fins};
pub use heightfield_mesh::{heightfield_mesh, mesh_stride, HeightfieldMesh, VertexColorFn, DEFAULT_MAX_SIDE_SAMPLES};
pub use isosurface::{extract_isosurface, min_crossing, ScalarField};
pub use lod::{
    sample_spacing, simplify_levels, simplify_levels_with, simplify_within, sliver_height, Border, Lod,
    SIMPLIFIER_MARGIN,
};
pub use normals::recompute_normals;
pub use rtin::{vertical_deviation, Rtin};
pub use smooth::{smooth, Smoothing};
pub use types::{bottom_centre, MaterialKind, Mesh, Scene, SceneNode};
