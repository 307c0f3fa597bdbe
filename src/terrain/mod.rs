//! Heightfields and where they come from.

mod extent;
mod fractal;
mod heightfield;
mod heightmap_png;
mod image_upload;
mod source;

pub use extent::TerrainExtent;
pub use fractal::generate_fractal;
pub use heightfield::Heightfield;
pub use heightmap_png::{decode_heightmap_png, png_header_dimensions, HeightmapDecodeError};
pub use image_upload::ImageUpload;
pub use source::{resolve, FractalParams, HeightmapUpload, TerrainError, TerrainLookup, TerrainSource};
