//! Hypsometric tint: a colour for each height, shared by the preview picture and the mesh's
//! vertex colours so both read the same way.
//!
//! Heights below the sea level (0 m unless a kind knows another, such as deform-terrain's mask
//! water level) are water — light blue at the shore to deep blue at the lowest sample — when
//! any sample lies below it; land runs greens → browns → greys → white from its lowest (or the
//! shore) to its highest sample, relative to the field's own relief so any scale reads well.

/// Land colours (sRGB) at fractions of the land's relief.
const LAND: [(f32, [f32; 3]); 8] = [
    (0.00, [56.0, 118.0, 64.0]),
    (0.12, [100.0, 150.0, 80.0]),
    (0.30, [170.0, 180.0, 105.0]),
    (0.48, [196.0, 166.0, 110.0]),
    (0.64, [158.0, 116.0, 78.0]),
    (0.80, [135.0, 125.0, 118.0]),
    (0.92, [190.0, 190.0, 190.0]),
    (1.00, [250.0, 250.0, 250.0]),
];

/// Water colours (sRGB) at fractions of the depth below 0 m, shore to deepest.
const WATER: [(f32, [f32; 3]); 3] =
    [(0.0, [140.0, 196.0, 230.0]), (0.4, [60.0, 128.0, 190.0]), (1.0, [24.0, 62.0, 130.0])];

/// The tint for one heightfield's range of heights.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tint {
    /// Deepest height (m) when the field has water, else `None`.
    sea_floor_m: Option<f32>,
    sea_level_m: f32,
    land_lo_m: f32,
    land_hi_m: f32,
}

impl Tint {
    /// A tint spanning `z_min..=z_max` metres, the sea at 0 m.
    pub fn new(z_min: f32, z_max: f32) -> Self {
        Self::with_sea_level(z_min, z_max, 0.0)
    }

    /// A tint spanning `z_min..=z_max` metres, the sea at `sea_level_m`.
    pub fn with_sea_level(z_min: f32, z_max: f32, sea_level_m: f32) -> Self {
        if z_min < sea_level_m {
            Self { sea_floor_m: Some(z_min), sea_level_m, land_lo_m: sea_level_m, land_hi_m: z_max.max(sea_level_m) }
        } else {
            Self { sea_floor_m: None, sea_level_m, land_lo_m: z_min, land_hi_m: z_max }
        }
    }

    /// Whether a height is drawn as water.
    pub fn is_water(&self, height_m: f32) -> bool {
        self.sea_floor_m.is_some() && height_m < self.sea_level_m
    }

    /// The sRGB colour of a height, each channel in 0..=255 (unrounded, so shading can scale it
    /// before quantising).
    pub fn srgb(&self, height_m: f32) -> [f32; 3] {
        match self.sea_floor_m {
            Some(floor) if height_m < self.sea_level_m => {
                ramp(&WATER, (self.sea_level_m - height_m) / (self.sea_level_m - floor))
            }
            _ => {
                let span = self.land_hi_m - self.land_lo_m;
                let t = if span > 0.0 { (height_m - self.land_lo_m) / span } else { 0.0 };
                ramp(&LAND, t)
            }
        }
    }

    /// The colour as opaque sRGB bytes, for vertex colours.
    pub fn srgba8(&self, height_m: f32) -> [u8; 4] {
        let [r, g, b] = self.srgb(height_m);
        [r.round() as u8, g.round() as u8, b.round() as u8, 255]
    }
}

/// Piecewise-linear colour at `t` (clamped to the ramp's ends).
fn ramp(stops: &[(f32, [f32; 3])], t: f32) -> [f32; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(stops[0].0, stops[stops.len() - 1].0) };
    let k = stops.partition_point(|s| s.0 < t).clamp(1, stops.len() - 1);
    let ((t0, c0), (t1, c1)) = (stops[k - 1], stops[k]);
    let f = if t1 > t0 { (t - t0) / (t1 - t0) } else { 0.0 };
    [0, 1, 2].map(|i| c0[i] + (c1[i] - c0[i]) * f)
}

#[cfg(test)]
mod tests {
    /// The playground draws its height legend from a copy of these stops
    /// (`web/src/hypsometric.ts`): the copy must be these numbers, or the legend lies.
    #[test]
    fn the_playgrounds_legend_has_these_stops() {
        let ts = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/web/src/hypsometric.ts")).unwrap();
        let stops = |name: &str| -> Vec<(f32, [f32; 3])> {
            let start = ts.find(&format!("const {name}")).unwrap_or_else(|| panic!("{name} in hypsometric.ts"));
            let block = &ts[start..start + ts[start..].find("];").unwrap()];
            block
                .lines()
                .filter_map(|l| {
                    let nums: Vec<f32> = l
                        .split(|c: char| !(c.is_ascii_digit() || c == '.'))
                        .filter(|t| !t.is_empty())
                        .map(|t| t.parse().unwrap())
                        .collect();
                    (nums.len() == 4).then(|| (nums[0], [nums[1], nums[2], nums[3]]))
                })
                .collect()
        };
        assert_eq!(stops("LAND"), LAND.to_vec());
        assert_eq!(stops("WATER"), WATER.to_vec());
    }

    use super::*;

    #[test]
    fn land_runs_green_to_white() {
        let tint = Tint::new(10.0, 110.0);
        let low = tint.srgb(10.0);
        assert!(low[1] > low[0] && low[1] > low[2], "lowland is green: {low:?}");
        assert_eq!(tint.srgba8(110.0), [250, 250, 250, 255]);
        assert_eq!(tint.srgb(10.0 + 48.0), LAND[3].1);
        assert!(!tint.is_water(10.0));
    }

    #[test]
    fn below_zero_is_blue_only_when_there_is_water() {
        let tint = Tint::new(-40.0, 60.0);
        assert!(tint.is_water(-1.0));
        let deep = tint.srgb(-40.0);
        assert_eq!(deep, WATER[2].1);
        assert_eq!(tint.srgb(0.0), LAND[0].1);
        assert_eq!(tint.srgb(60.0), LAND[7].1);
    }

    #[test]
    fn a_sea_level_of_the_kinds_moves_the_shore() {
        let tint = Tint::with_sea_level(0.0, 100.0, 50.0);
        assert!(tint.is_water(49.9) && !tint.is_water(50.0));
        assert_eq!(tint.srgb(0.0), WATER[2].1);
        assert_eq!(tint.srgb(30.0), ramp(&WATER, 0.4));
        assert_eq!(tint.srgb(50.0), LAND[0].1);
        assert_eq!(tint.srgb(100.0), LAND[7].1);
        assert!(!Tint::new(0.0, 100.0).is_water(30.0));
    }

    #[test]
    fn flat_field_is_one_colour() {
        let tint = Tint::new(5.0, 5.0);
        assert_eq!(tint.srgb(5.0), LAND[0].1);
    }
}
