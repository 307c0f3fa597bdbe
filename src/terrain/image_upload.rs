//! A PNG a request carries besides terrain (e.g. a joint map): sent inline or named by the
//! sha256 of one sent before, stored by content like an uploaded heightmap.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::heightmap_png::{decode_base64, png_dimensions};
use super::{HeightmapDecodeError, TerrainError, TerrainLookup};
use crate::validate::{Limits, Validator};

/// A PNG file: `png_base64` inline, or `png_sha256` naming one this server was sent before —
/// exactly one of the two. An inline PNG is stored when the job is accepted and the stored
/// request then names it by `png_sha256`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ImageUpload {
    /// The PNG file, base64-encoded (standard alphabet). Its width × height must be at most the
    /// server's grid cap (4097 × 4097 pixels by default; more is answered with 413).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub png_base64: Option<String>,
    /// The sha256 (lowercase hex) of a PNG this server was sent before.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(pattern = "^[0-9a-f]{64}$")]
    pub png_sha256: Option<String>,
}

/// Whether `sha` is a sha256 in lowercase hex.
pub(super) fn is_sha256_hex(sha: &str) -> bool {
    sha.len() == 64 && sha.bytes().all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b))
}

/// Check a `png_base64` / `png_sha256` pair inside the validator's current field: exactly one
/// given, a well-formed hash, or an inline PNG whose header reads and whose pixel count is
/// within `max_pixels`. Returns the inline PNG's (width, height) when it has one.
pub(super) fn validate_png_pair(
    v: &mut Validator,
    png_base64: Option<&str>,
    png_sha256: Option<&str>,
    max_pixels: u64,
    noun: &str,
) -> Option<(u64, u64)> {
    match (png_base64, png_sha256) {
        (Some(_), Some(_)) => v.error("png_sha256", "give png_base64 or png_sha256, not both"),
        (None, None) => v.error("png_base64", "is missing (or name an earlier upload by png_sha256)"),
        (None, Some(sha)) => {
            if !is_sha256_hex(sha) {
                v.error("png_sha256", "must be a sha256 in lowercase hex (64 characters)");
            }
        }
        (Some(text), None) => match png_dimensions(text) {
            Err(e) => v.error("png_base64", e.to_string()),
            Ok((w, h)) if w * h > max_pixels => {
                v.too_large("png_base64", format!("{w}×{h} pixels is more than the cap of {max_pixels} {noun}"))
            }
            Ok(dims) => return Some(dims),
        },
    }
    None
}

impl ImageUpload {
    /// Validate inside the current field; the pixel count is capped by `limits.max_grid_cells`.
    pub fn validate_in(&self, v: &mut Validator, limits: &Limits) -> Option<(u64, u64)> {
        validate_png_pair(v, self.png_base64.as_deref(), self.png_sha256.as_deref(), limits.max_grid_cells, "pixels")
    }

    /// The sha256 of an upload named without being sent.
    pub fn input_ref(&self) -> Option<&str> {
        match (&self.png_base64, &self.png_sha256) {
            (None, Some(sha)) => Some(sha),
            _ => None,
        }
    }

    /// Take the inline PNG out, leaving its sha256: `(sha256, bytes)` for the store.
    pub fn take_upload(&mut self) -> Result<Option<(String, Vec<u8>)>, HeightmapDecodeError> {
        let Some(text) = self.png_base64.take() else { return Ok(None) };
        let png = decode_base64(&text)?;
        let sha = hex::encode(<sha2::Sha256 as sha2::Digest>::digest(&png));
        self.png_sha256 = Some(sha.clone());
        Ok(Some((sha, png)))
    }

    /// The PNG bytes, inline or from the store.
    pub fn bytes(&self, lookup: &dyn TerrainLookup) -> Result<Vec<u8>, TerrainError> {
        match (&self.png_base64, &self.png_sha256) {
            (Some(text), _) => Ok(decode_base64(text)?),
            (None, Some(sha)) => lookup.input(sha).map_err(TerrainError::Input),
            (None, None) => Err(TerrainError::Input("the request names no PNG".into())),
        }
    }

    /// The inline PNG's bytes, when it was sent inline (for checks at validation time).
    pub fn inline_bytes(&self) -> Option<Result<Vec<u8>, HeightmapDecodeError>> {
        self.png_base64.as_deref().map(decode_base64)
    }
}
