//! Meshes: the plain data every kind writes, and heightfield meshing.
//!
//! Units are metres with Y up; front faces wind counter-clockwise (see [`Mesh`]).

mod heightfield_mesh;
mod types;

pub use heightfield_mesh::{heightfield_mesh, mesh_stride, HeightfieldMesh, VertexColorFn, DEFAULT_MAX_SIDE_SAMPLES};
pub use types::{MaterialKind, Mesh, Scene, SceneNode};
