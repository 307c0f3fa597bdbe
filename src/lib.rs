//! Landform: an HTTP terrain-generation service.
//!
//! Layers (see DESIGN.md): `sims` (pure algorithms, one folder per job kind), `terrain`
//! (heightfields and their sources), `mesh`, `export` (glb/png writers), `model` (the job
//! model, below both engine and stores), `jobs` (the engine, the `JobKind` trait), `store`
//! (the `JobStore` trait and its SQLite form), `http`.
//!
//! Conventions: lengths in metres, Y up; a heightfield's rows run along +Z and its columns
//! along +X, with the origin at the grid's corner.

pub mod config;
pub mod export;
pub mod http;
pub mod jobs;
pub mod mesh;
pub mod model;
pub mod sims;
pub mod stop;
pub mod store;
pub mod supervisor;
pub mod terrain;
pub mod validate;
