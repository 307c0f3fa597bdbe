//! Bubbles (paper section 4, Figure 5): the volume around a voxel whose air-to-rock ratio
//! estimates the local curvature, stored as the lookup table of runs a removal increments.

use super::grid::Exposure;
use super::params::Bubble;

/// The cells `(x_lo..=x_hi, dy, dz)` of a bubble in one row, relative to its centre.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Run {
    pub dz: i32,
    pub x_lo: i32,
    pub x_hi: i32,
}

/// A bubble as rows of runs, grouped by `dy`. The same table serves two ways: counting the air
/// around a voxel `v` (cells `v + o`), and — the paper's lookup table of increments — finding
/// the voxels whose bubble a removed voxel `u` was in (voxels `u − o`), each of which gains
/// exactly one cell of air.
#[derive(Clone, Debug, PartialEq)]
pub struct BubbleTable {
    pub dy_min: i32,
    pub dy_max: i32,
    /// `rows[dy - dy_min]`: runs ordered by `dz`.
    pub rows: Vec<Vec<Run>>,
    /// Cells in the bubble, its centre included.
    pub cells: u32,
    /// Largest |offset| along X, Y, Z.
    pub reach: [i32; 3],
    /// Cells in the bubble's central plane across X, Y and Z (offset 0 along that axis).
    pub central: [u32; 3],
    /// The air-to-rock ratio is raised to this power.
    ratio_exponent: f32,
}

impl BubbleTable {
    /// The table of `bubble`, its decimation growing with the air-to-rock ratio raised to
    /// `ratio_exponent` (1 in the paper).
    pub fn new(bubble: &Bubble, ratio_exponent: f32) -> Self {
        let [rx, ry, rz] = bubble.radii();
        let gumdrop = matches!(bubble, Bubble::Gumdrop { .. });
        let inside = |dx: i32, dy: i32, dz: i32| {
            let q = (dx as f32 / rx).powi(2) + (dy as f32 / ry).powi(2) + (dz as f32 / rz).powi(2);
            q <= 1.0 + 1e-6 && !(gumdrop && dy < 0)
        };
        let (ex, ey, ez) = (rx.floor() as i32, ry.floor() as i32, rz.floor() as i32);
        let dy_min = if gumdrop { 0 } else { -ey };
        let mut rows = Vec::new();
        let mut cells = 0;
        for dy in dy_min..=ey {
            let mut row = Vec::new();
            for dz in -ez..=ez {
                let xs: Vec<i32> = (-ex..=ex).filter(|&dx| inside(dx, dy, dz)).collect();
                if let (Some(&x_lo), Some(&x_hi)) = (xs.first(), xs.last()) {
                    cells += xs.len() as u32;
                    row.push(Run { dz, x_lo, x_hi });
                }
            }
            rows.push(row);
        }
        let mut central = [0u32; 3];
        for (dy, row) in (dy_min..=ey).zip(&rows) {
            for run in row {
                central[0] += (run.x_lo <= 0 && 0 <= run.x_hi) as u32;
                central[1] += if dy == 0 { (run.x_hi - run.x_lo + 1) as u32 } else { 0 };
                central[2] += if run.dz == 0 { (run.x_hi - run.x_lo + 1) as u32 } else { 0 };
            }
        }
        Self { dy_min, dy_max: ey, rows, cells, reach: [ex, ey, ez], central, ratio_exponent }
    }

    pub fn row(&self, dy: i32) -> &[Run] {
        if dy < self.dy_min || dy > self.dy_max {
            &[]
        } else {
            &self.rows[(dy - self.dy_min) as usize]
        }
    }

    /// Decimation per step for an exposed voxel with `air` of the bubble's cells empty (paper
    /// section 4: the air-to-rock ratio, scaled by the rate and divided by the resistance).
    ///
    /// The ratio is the one of a bubble centred on the surface, as the paper's Figure 5 draws
    /// it, not on the voxel's centre half a voxel inside. Centred on the voxel, a flat face
    /// counts the bubble's whole central plane across it as rock, and a bubble thin across a
    /// face (where that plane is a large part of it) sees the face as flatter than a bubble
    /// deep across it: an ellipsoid bubble long along Z weathered the Z faces fastest and left
    /// the rock 32 % short along its long axis. Moving the centre half a voxel out along the
    /// surface's normal (from the 26 cells around) turns half of the central plane across
    /// that normal from rock to air, so a flat face of any orientation holds as much air as
    /// rock under any symmetric bubble. On an edge or a corner the move is the same half voxel
    /// (the surface point nearest the voxel's centre is no farther), and a staircase of voxels
    /// on a slanted face moves no more than a flat face: a round column stays round.
    pub fn decimation(&self, air: u16, exposure: Exposure, rate: f32, resistance: f32) -> f32 {
        let t = exposure.towards.map(f32::from);
        let norm2 = t.iter().map(|v| v * v).sum::<f32>();
        let plane = if norm2 > 0.0 {
            (0..3).map(|k| t[k] * t[k] / norm2 * self.central[k] as f32).sum::<f32>()
        } else {
            // Air all around in balance (a thin fin or a lone voxel): no one plane.
            (0..3).map(|k| self.central[k] as f32).sum::<f32>() / 3.0
        };
        let shift = 0.5 * plane;
        let cells = self.cells as f32;
        let air = (air as f32 + shift).min(cells - 0.5);
        let ratio = f64::from(air / (cells - air));
        let curvature = if self.ratio_exponent == 1.0 { ratio } else { ratio.powf(f64::from(self.ratio_exponent)) };
        // A lone voxel under a high exponent would overflow to infinity (and infinity × 0 is
        // NaN in the event-based update's bookkeeping); past 1 a step it is gone either way.
        (f64::from(rate) * curvature / f64::from(resistance)).min(MAX_DECIMATION) as f32
    }
}

/// The most decimation a voxel can take in a step: far past the 1 that removes it at once.
const MAX_DECIMATION: f64 = 1e6;

#[cfg(test)]
mod tests {
    use super::*;

    const FLAT: Exposure = Exposure { air: 9, towards: [0, 9, 0] };

    fn count(t: &BubbleTable) -> u32 {
        t.rows.iter().flatten().map(|r| (r.x_hi - r.x_lo + 1) as u32).sum()
    }

    #[test]
    fn sphere_of_radius_one_is_the_centre_and_six_faces() {
        let t = BubbleTable::new(&Bubble::Sphere { radius: 1.0 }, 1.0);
        assert_eq!(t.cells, 7);
        assert_eq!(count(&t), 7);
    }

    #[test]
    fn sphere_of_radius_four_holds_about_its_volume() {
        let t = BubbleTable::new(&Bubble::Sphere { radius: 4.0 }, 1.0);
        assert_eq!(t.cells, 257);
        let ideal = 4.0 / 3.0 * std::f32::consts::PI * 64.0;
        assert!((t.cells as f32 - ideal).abs() / ideal < 0.05);
    }

    #[test]
    fn gumdrop_is_the_upper_half_with_the_centre_plane() {
        let t = BubbleTable::new(&Bubble::Gumdrop { radius: 4.0 }, 1.0);
        assert_eq!(t.dy_min, 0);
        let plane = count(&BubbleTable { rows: vec![t.rows[0].clone()], ..t.clone() });
        assert_eq!(t.cells, (257 - plane) / 2 + plane);
    }

    #[test]
    fn ellipsoid_reaches_its_radii() {
        let t = BubbleTable::new(&Bubble::Ellipsoid { radii: [2.0, 5.0, 3.0] }, 1.0);
        assert_eq!(t.reach, [2, 5, 3]);
        assert_eq!((t.dy_min, t.dy_max), (-5, 5));
    }

    #[test]
    fn a_flat_face_holds_as_much_air_as_rock_under_any_bubble_and_orientation() {
        // A face voxel's bubble, centred on the voxel, holds as air the cells past its face:
        // half of those off its central plane, by symmetry. Centred on the surface, the ratio
        // is 1 whatever the bubble's shape and the face's axis.
        for bubble in [Bubble::Ellipsoid { radii: [6.0, 2.5, 2.5] }, Bubble::Ellipsoid { radii: [2.0, 7.0, 3.0] }] {
            let t = BubbleTable::new(&bubble, 1.0);
            for k in 0..3 {
                let mut towards = [0i8; 3];
                towards[k] = 9;
                let air = ((t.cells - t.central[k]) / 2) as u16;
                let d = t.decimation(air, Exposure { air: 9, towards }, 0.05, 1.0);
                assert!((d - 0.05).abs() < 1e-6, "{bubble:?} axis {k}: {d}");
            }
        }
    }

    #[test]
    fn corners_weather_faster_than_faces() {
        let t = BubbleTable::new(&Bubble::Sphere { radius: 4.0 }, 1.0);
        // A face voxel sees the half-space above its plane as air; a corner seven octants.
        let face_air = ((t.cells - 49) / 2) as u16;
        assert!(t.decimation(face_air * 3 / 2, FLAT, 1.0, 1.0) > 2.0 * t.decimation(face_air, FLAT, 1.0, 1.0));
        assert!(t.decimation(face_air, FLAT, 1.0, 2.0) < t.decimation(face_air, FLAT, 1.0, 1.0));
        // A higher exponent favours the corner more.
        let sharp = BubbleTable::new(&Bubble::Sphere { radius: 4.0 }, 8.0);
        let ratio =
            |t: &BubbleTable| t.decimation(face_air * 3 / 2, FLAT, 1.0, 1.0) / t.decimation(face_air, FLAT, 1.0, 1.0);
        assert!(ratio(&sharp) > 10.0 * ratio(&t));
    }
}
