use super::{Heightfield, HeightmapUpload};
use crate::validate::Limits;

#[derive(Debug, thiserror::Error)]
pub enum HeightmapDecodeError {
    #[error("{0}")]
    Invalid(String),
}

pub fn decode_heightmap_png(u: &HeightmapUpload, limits: &Limits) -> Result<Heightfield, HeightmapDecodeError> {
    let _ = (u, limits);
    todo!("helper C")
}

/// (width, height) from the PNG header without decoding the pixels.
pub fn png_dimensions(png_base64: &str) -> Result<(u64, u64), HeightmapDecodeError> {
    let _ = png_base64;
    todo!("helper C")
}
