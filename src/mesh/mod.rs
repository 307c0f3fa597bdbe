//! Meshes: the plain data every kind writes, and heightfield meshing.
//!
//! Units are metres with Y up; front faces wind counter-clockwise (see [`Mesh`]).

mod gpu_order;
mod heightfield_mesh;
mod isosurface;
mod normals;
mod smooth;
mod types;

pub use gpu_order::GpuOrder;
pub use heightfield_mesh::{heightfield_mesh, mesh_stride, HeightfieldMesh, VertexColorFn, DEFAULT_MAX_SIDE_SAMPLES};
pub use isosurface::{extract_isosurface, ScalarField};
pub use normals::recompute_normals;
pub use smooth::{smooth, Smoothing};
pub use types::{MaterialKind, Mesh, Scene, SceneNode};
