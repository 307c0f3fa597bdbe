//! Paths, moves and passes (paper §2.1): a blade pushed along each segment of a 3-D
//! polyline. One segment's sweep is a move; the whole path is a pass.

use std::f64::consts::{PI, TAU};

use serde::{Deserialize, Serialize};

use super::apply::{affected_cells, apply_over, Bounds, Footprint, Frame, Patch};
use super::blade::{Blade, BladeGeometry};
use super::combine::Operator;
use super::params::{PassOp, PathBase, PlanPoint, Window};
use crate::terrain::Heightfield;

/// A path vertex with its height resolved: what the sequence records, so that a replay needs
/// no terrain lookups.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PathPoint {
    pub x: f32,
    pub z: f32,
    /// Absolute height of the path here, metres.
    pub height: f32,
}

/// One move: the blade pushed along one segment of a pass's path.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MoveStep {
    /// Which pass (0-based, counting passes only).
    pub pass: u32,
    /// Which segment of the pass's path (0-based): from vertex `segment` to `segment + 1`.
    pub segment: u32,
    /// The path vertex before `from` (null on a pass's first move): at `from` the blade first
    /// turns from that segment's heading to this one's.
    #[serde(default)]
    pub previous: Option<PlanPoint>,
    pub from: PathPoint,
    pub to: PathPoint,
    /// The blade, with its profile at `from`.
    pub blade: Blade,
    pub operator: Operator,
    /// The profile at `to` when keyframes change it along the move: the relief blends from the
    /// blade's profile to this one linearly with the distance along the segment.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub profile_to: Option<Vec<[f32; 2]>>,
    /// How the base runs between `from` and `to` (`ground`: over the terrain as the pass
    /// started, which a replay rebuilds before applying the pass).
    #[serde(default, skip_serializing_if = "PathBase::is_linear")]
    pub base: PathBase,
}

/// The moves of a pass, its relative vertices resolved against `hf` as the pass starts.
pub fn resolve_pass(hf: &Heightfield, pass_index: u32, pass: &PassOp) -> Vec<MoveStep> {
    let points: Vec<PathPoint> = pass
        .path
        .iter()
        .map(|v| PathPoint { x: v.x, z: v.z, height: v.height.unwrap_or_else(|| hf.sample(v.x, v.z)) })
        .collect();
    let profiles = vertex_profiles(pass);
    points
        .windows(2)
        .enumerate()
        .map(|(k, w)| MoveStep {
            pass: pass_index,
            segment: k as u32,
            previous: k.checked_sub(1).map(|i| PlanPoint { x: points[i].x, z: points[i].z }),
            from: w[0],
            to: w[1],
            blade: Blade { profile: profiles[k].clone(), ..pass.blade.clone() },
            operator: pass.operator,
            profile_to: (profiles[k + 1] != profiles[k]).then(|| profiles[k + 1].clone()),
            base: pass.base,
        })
        .collect()
}

/// The blade's profile at every path vertex: the keyframes (the blade's own profile at vertex
/// 0 unless one is there), blended by arc length between them, held after the last.
fn vertex_profiles(pass: &PassOp) -> Vec<Vec<[f32; 2]>> {
    let path = &pass.path;
    let mut arc = vec![0.0f64];
    for w in path.windows(2) {
        arc.push(
            arc.last().expect("starts at 0") + (w[1].x as f64 - w[0].x as f64).hypot(w[1].z as f64 - w[0].z as f64),
        );
    }
    let mut keys: Vec<(usize, &[[f32; 2]])> =
        pass.keyframes.iter().map(|k| (k.vertex as usize, &k.profile[..])).collect();
    if keys.first().is_none_or(|k| k.0 != 0) {
        keys.insert(0, (0, &pass.blade.profile));
    }
    (0..path.len())
        .map(|i| {
            // The last keyframe at or before i, and the next after it.
            let k = keys.partition_point(|key| key.0 <= i) - 1;
            match keys.get(k + 1) {
                Some(&(b, next)) if i != keys[k].0 => {
                    let a = keys[k].0;
                    let t = (arc[i] - arc[a]) / (arc[b] - arc[a]);
                    super::blade::blend_profiles(keys[k].1, next, t)
                }
                _ => keys[k].1.to_vec(),
            }
        })
        .collect()
}

/// A move's sweep in plan. A point with path-local coordinates (s along, d across) meets
/// the blade at u · w/2 = (d − offset) / cos(angle) when the blade's centre is at
/// s0 = s − (u · w/2) · sin(angle); it is in the move if |u| ≤ 1 and s0 ∈ [0, L]. Its base
/// is the path's height interpolated at s0, its relief the blade's profile at u.
///
/// A move after a bend also holds the pivot: where the blade, held at the bend's vertex,
/// turns from the previous segment's heading to this one's. That fills the wedge on the
/// outside of the bend that neither segment's sweep reaches (base: the vertex's height).
pub struct MoveGeometry<'g> {
    frame: Frame,
    length: f64,
    h0: f64,
    h1: f64,
    blade: BladeGeometry,
    /// The profile at the move's end, when keyframes change it.
    blade_to: Option<BladeGeometry>,
    /// With a base following the ground: the grid as the pass started.
    ground: Option<&'g Heightfield>,
    pivot: Option<Pivot>,
    bounds: Bounds,
}

/// The blade turning about a path vertex.
struct Pivot {
    /// The previous segment's frame, moved to the vertex.
    frame: Frame,
    /// Length of the previous segment.
    previous_length: f64,
    /// Signed turn from the previous heading to this one, radians, positive to the right.
    turn: f64,
    /// Farthest reach of the blade from the vertex.
    reach: f64,
}

impl<'g> MoveGeometry<'g> {
    /// The move's geometry; `ground` is the grid as the pass started, which a base following
    /// the ground reads (a copy: the pass's moves write the grid itself).
    pub fn new(step: &MoveStep, ground: Option<&'g Heightfield>) -> Self {
        let from = (step.from.x as f64, step.from.z as f64);
        let (frame, length) = Frame::between(from, (step.to.x as f64, step.to.z as f64));
        let blade = BladeGeometry::new(&step.blade);
        let corners = [(0.0, -1.0), (0.0, 1.0), (length, -1.0), (length, 1.0)].map(|(s0, u)| {
            let (along, across) = blade.end(u);
            frame.world(s0 + along, across)
        });
        let mut bounds = Bounds::around(corners);
        let pivot = step.previous.and_then(|p| {
            let (previous, previous_length) = Frame::between((p.x as f64, p.z as f64), from);
            // The new heading in the old frame: along its tangent and its right-hand normal.
            let along = frame.tx * previous.tx + frame.tz * previous.tz;
            let across = frame.tz * previous.tx - frame.tx * previous.tz;
            let turn = across.atan2(along);
            if turn == 0.0 || !previous_length.is_finite() {
                return None;
            }
            let reach = [-1.0, 1.0].map(|u| blade.end(u)).iter().map(|&(a, b)| a.hypot(b)).fold(0.0, f64::max);
            let square = Bounds::square(from.0, from.1, reach);
            bounds = Bounds::around([
                (bounds.min_x, bounds.min_z),
                (bounds.max_x, bounds.max_z),
                (square.min_x, square.min_z),
                (square.max_x, square.max_z),
            ]);
            Some(Pivot { frame: Frame { ox: from.0, oz: from.1, ..previous }, previous_length, turn, reach })
        });
        let blade_to =
            step.profile_to.as_ref().map(|p| BladeGeometry::new(&Blade { profile: p.clone(), ..step.blade.clone() }));
        let ground = ground.filter(|_| step.base == PathBase::Ground);
        let (h0, h1) = (step.from.height as f64, step.to.height as f64);
        let mut g = Self { frame, length, h0, h1, blade, blade_to, ground, pivot, bounds };
        if g.ground.is_some() {
            // The vertices' heights above the ground, interpolated between them.
            (g.h0, g.h1) = (h0 - g.ground_at(0.0), h1 - g.ground_at(length));
        }
        g
    }

    /// The pass-start ground under the blade's centre `s0` along the segment (0 with a linear
    /// base), bilinear.
    #[inline]
    fn ground_at(&self, s0: f64) -> f64 {
        let Some(g) = self.ground else { return 0.0 };
        let (x, z) = self.frame.world(s0, 0.0);
        g.sample(x as f32, z as f32) as f64
    }

    /// The blade coordinate u at which the turning blade passes over a point outside both
    /// segments' sweeps, if it does.
    fn pivot_u(&self, pivot: &Pivot, x: f64, z: f64) -> Option<f64> {
        let b = &self.blade;
        let (s, d) = pivot.frame.local(x, z);
        let rho2 = s * s + d * d;
        if rho2 > pivot.reach * pivot.reach {
            return None;
        }
        if let Some((_, s0)) = b.locate(s, d) {
            if (-pivot.previous_length..=0.0).contains(&s0) {
                return None; // in the previous move's sweep
            }
        }
        // Blade points at distance rho from the vertex: |(a sin, offset + a cos)| = rho.
        let (sin, cos, offset) = (b.sin_angle, b.cos_angle, b.offset_m);
        let disc = rho2 - offset * offset * sin * sin;
        if disc < 0.0 {
            return None;
        }
        let root = disc.sqrt();
        let point_angle = d.atan2(s);
        let mut best: Option<(f64, f64)> = None;
        for a in [-offset * cos - root, -offset * cos + root] {
            if a.abs() > b.half_width_m {
                continue;
            }
            // The turn that carries this blade point onto the point, in (−π, π].
            let mut turned = point_angle - (offset + a * cos).atan2(a * sin);
            if turned > PI {
                turned -= TAU;
            } else if turned <= -PI {
                turned += TAU;
            }
            let within = if pivot.turn > 0.0 {
                (0.0..=pivot.turn).contains(&turned)
            } else {
                (pivot.turn..=0.0).contains(&turned)
            };
            // Where two blade points pass, the one that passes last stands.
            if within && best.is_none_or(|(t, _)| turned.abs() > t) {
                best = Some((turned.abs(), a));
            }
        }
        best.map(|(_, a)| a / b.half_width_m)
    }
}

impl Footprint for MoveGeometry<'_> {
    fn bounds(&self) -> Bounds {
        self.bounds
    }

    #[inline]
    fn sample(&self, x: f64, z: f64) -> Option<(f64, f64)> {
        let (s, d) = self.frame.local(x, z);
        if let Some((u, s0)) = self.blade.locate(s, d) {
            if (0.0..=self.length).contains(&s0) {
                let t = s0 / self.length;
                let base = self.h0 + (self.h1 - self.h0) * t + self.ground_at(s0);
                let relief = match &self.blade_to {
                    Some(to) => (1.0 - t) * self.blade.profile(u) + t * to.profile(u),
                    None => self.blade.profile(u),
                };
                return Some((base, relief));
            }
        }
        let pivot = self.pivot.as_ref()?;
        let u = self.pivot_u(pivot, x, z)?;
        Some((self.h0 + self.ground_at(0.0), self.blade.profile(u)))
    }
}

/// Apply the moves of one pass (all of it, or its first moves), calling `after_move` with
/// each move's index once it is done; stops at the first error `after_move` returns.
///
/// Every move combines its shape with the surface as the pass found it (paper §2.4), kept
/// in a copy of the region the pass can reach, and writes the grid; where moves overlap the
/// later one's result overwrites the earlier's. So each sample ends as the last move that
/// covers it made it, and the grid after move k is the grid a pass cut short after move k
/// leaves.
pub fn apply_pass<E>(
    hf: &mut Heightfield,
    moves: &[MoveStep],
    window: Option<&Window>,
    mut after_move: impl FnMut(usize) -> Result<(), E>,
) -> Result<(), E> {
    let ground = moves.iter().any(|m| m.base == PathBase::Ground).then(|| hf.clone());
    let geometry: Vec<MoveGeometry> = moves.iter().map(|m| MoveGeometry::new(m, ground.as_ref())).collect();
    let reach = geometry.iter().map(|g| g.bounds).reduce(|a, b| a.union(&b));
    let Some(cells) = reach.and_then(|reach| affected_cells(hf, reach, window)) else {
        // Nothing of the grid in reach: every move leaves it as it is.
        return (0..moves.len()).try_for_each(after_move);
    };
    let pass_start = Patch::copy(hf, cells);
    for (k, (step, g)) in moves.iter().zip(&geometry).enumerate() {
        apply_over(hf, &pass_start, g, step.operator, window);
        after_move(k)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sims::bulldoze::params::{PathVertex, ProfileKeyframe};

    fn vertex(x: f32, z: f32, height: Option<f32>) -> PathVertex {
        PathVertex { x, z, height }
    }

    fn blade(width_m: f32, profile: &[[f32; 2]]) -> Blade {
        Blade { width_m, profile: profile.to_vec(), offset_m: 0.0, angle_deg: 0.0 }
    }

    /// Resolve and apply one pass; returns its moves.
    fn bulldoze(hf: &mut Heightfield, path: Vec<PathVertex>, blade: Blade, operator: Operator) -> Vec<MoveStep> {
        let moves = resolve_pass(
            hf,
            0,
            &PassOp { path, blade, operator, keyframes: Vec::new(), contour: None, base: PathBase::Linear },
        );
        apply_pass(hf, &moves, None, |_| Ok::<(), ()>(())).unwrap();
        moves
    }

    fn close(a: f32, b: f64, tolerance: f64) -> bool {
        (a as f64 - b).abs() <= tolerance
    }

    #[test]
    fn replace_leaves_the_blade_profile_across_an_absolute_path() {
        let trapezoid = [[-1.0, 0.0], [-0.5, -2.0], [0.5, -2.0], [1.0, 0.0]];
        let v_shape = [[-1.0, 1.0], [0.0, -3.0], [1.0, 0.5]];
        for profile in [&trapezoid[..], &v_shape[..]] {
            let mut hf = Heightfield::flat(121, 81, 0.5, 0.0);
            let path = vec![vertex(10.0, 20.0, Some(5.0)), vertex(50.0, 20.0, Some(9.0))];
            let moves = bulldoze(&mut hf, path, blade(8.0, profile), Operator::Replace);
            let g = BladeGeometry::new(&moves[0].blade);
            for x_col in [40, 60, 80] {
                // Path height interpolated between 5 m at x = 10 and 9 m at x = 50.
                let x = x_col as f64 * 0.5;
                let path_height = 5.0 + 4.0 * (x - 10.0) / 40.0;
                for row in 0..81 {
                    let d = row as f64 * 0.5 - 20.0;
                    let got = hf.get(x_col, row);
                    if d.abs() <= 4.0 {
                        let want = path_height + g.profile(d / 4.0);
                        assert!(close(got, want, 1e-4), "x {x} d {d}: {got} vs {want}");
                    } else {
                        assert_eq!(got, 0.0, "outside the swath at x {x} d {d}");
                    }
                }
            }
            // Nothing changes before the path starts or after it ends.
            for row in 0..81 {
                assert_eq!(hf.get(19, row), 0.0);
                assert_eq!(hf.get(101, row), 0.0);
            }
        }
    }

    #[test]
    fn a_keyframed_blade_has_the_interpolated_profile_across_the_middle_of_each_segment() {
        // Flat at vertex 0, a V 4 m deep at vertex 2, vertex 1 between by arc length: at the
        // middle of segment 0 the blade is a quarter of the way (20 of 80 m), at the middle
        // of segment 1 three quarters.
        let flat = [[-1.0, 0.0], [1.0, 0.0]];
        let vee = [[-1.0, 0.0], [0.0, -4.0], [1.0, 0.0]];
        let mut hf = Heightfield::flat(121, 41, 1.0, 0.0);
        let path = vec![vertex(10.0, 20.0, Some(5.0)), vertex(50.0, 20.0, Some(5.0)), vertex(90.0, 20.0, Some(5.0))];
        let keyframes = vec![ProfileKeyframe { vertex: 2, profile: vee.to_vec() }];
        let pass = PassOp {
            path,
            blade: blade(8.0, &flat),
            operator: Operator::Replace,
            keyframes,
            contour: None,
            base: PathBase::Linear,
        };
        let moves = resolve_pass(&hf, 0, &pass);
        apply_pass(&mut hf, &moves, None, |_| Ok::<(), ()>(())).unwrap();
        // By hand: V(u) = −4 (1 − |u|); the blend at t is 5 + t · V(u), u = d / 4.
        for (x, t) in [(30, 0.25), (70, 0.75)] {
            for d in -4i32..=4 {
                let u = d as f64 / 4.0;
                let want = 5.0 + t * -4.0 * (1.0 - u.abs());
                let got = hf.get(x, (20 + d) as usize);
                assert!(close(got, want, 1e-5), "x {x} d {d}: {got} vs {want}");
            }
            assert_eq!(hf.get(x, 25), 0.0, "outside the blade");
        }
        // Recorded: each move's blade carries its start profile and the end one.
        assert_eq!(moves[0].blade.profile, flat.to_vec());
        assert_eq!(moves[1].profile_to.as_deref(), Some(&vee[..]));
        // Without keyframes nothing is recorded beyond the blade.
        let plain = resolve_pass(&hf, 0, &PassOp { keyframes: Vec::new(), ..pass });
        assert!(plain.iter().all(|m| m.profile_to.is_none()));
    }

    #[test]
    fn a_base_following_the_ground_rides_every_bump_between_vertices() {
        // Bumps every 20 m under a path with vertices 60 m apart: a linear base bridges them,
        // a ground base follows them, a 2 m cut below the pass-start ground everywhere.
        let bumps = |x: f32, z: f32| 10.0 + 3.0 * (x * std::f32::consts::PI / 10.0).sin() + 0.02 * z;
        let start = Heightfield::from_fn(141, 41, 1.0, bumps);
        let cut = [[-1.0, -2.0], [1.0, -2.0]];
        let path = vec![vertex(10.0, 20.0, None), vertex(70.0, 20.0, None), vertex(130.0, 20.0, None)];
        let run = |base: PathBase| {
            let mut hf = start.clone();
            let pass = PassOp {
                path: path.clone(),
                blade: blade(6.0, &cut),
                operator: Operator::Replace,
                keyframes: Vec::new(),
                contour: None,
                base,
            };
            let moves = resolve_pass(&hf, 0, &pass);
            apply_pass(&mut hf, &moves, None, |_| Ok::<(), ()>(())).unwrap();
            hf
        };
        let ground = run(PathBase::Ground);
        let linear = run(PathBase::Linear);
        let mut bridged = 0.0f32;
        for col in 10..=130 {
            for row in 18..=22 {
                let want = start.get(col, 20) - 2.0;
                assert!(
                    close(ground.get(col, row), want as f64, 1e-4),
                    "({col}, {row}): {} vs {want}",
                    ground.get(col, row)
                );
            }
            bridged = bridged.max((linear.get(col, 20) - (start.get(col, 20) - 2.0)).abs());
        }
        assert!(bridged > 2.0, "a linear base does not follow the bumps ({bridged})");
    }

    #[test]
    fn a_relative_path_follows_a_sloped_plane() {
        let plane = |x: f32, z: f32| 5.0 + 0.1 * x + 0.05 * z;
        let start = Heightfield::from_fn(101, 101, 1.0, plane);
        let cut = [[-1.0, -2.0], [1.0, -2.0]];
        // A bent path on grid points, with no heights: every vertex rides on the terrain.
        let path = || {
            vec![vertex(10.0, 30.0, None), vertex(40.0, 30.0, None), vertex(70.0, 60.0, None), vertex(90.0, 60.0, None)]
        };

        let mut hf = start.clone();
        let moves = bulldoze(&mut hf, path(), blade(6.0, &cut), Operator::Replace);
        for m in &moves {
            assert!(close(m.from.height, plane(m.from.x, m.from.z) as f64, 1e-4));
        }
        // Along the centreline the cut is 2 m deep everywhere.
        for (col, row) in
            (10..=40).map(|c| (c, 30)).chain((40..=70).map(|i| (i, i - 10))).chain((70..=90).map(|c| (c, 60)))
        {
            let depth = start.get(col, row) - hf.get(col, row);
            assert!(close(depth, 2.0, 1e-4), "depth {depth} at ({col}, {row})");
        }

        // With `add`, every sample in the swath drops by exactly 2 m, including where the
        // moves meet at the bends: no sample is cut twice.
        let mut hf = start.clone();
        bulldoze(&mut hf, path(), blade(6.0, &cut), Operator::Add);
        let mut cut_samples = 0;
        for (a, b) in start.heights_m.iter().zip(&hf.heights_m) {
            let dz = b - a;
            assert!(dz == 0.0 || close(dz, -2.0, 1e-4), "changed by {dz}");
            cut_samples += (dz != 0.0) as usize;
        }
        assert!(cut_samples > 500);
    }

    #[test]
    fn the_blade_pivots_round_the_outside_of_a_bend() {
        // A left turn at (50, 50): heading +X, then −Z. Its outside is the quadrant x > 50,
        // z > 50, which neither segment's sweep reaches.
        let path =
            || vec![vertex(10.0, 50.0, Some(20.0)), vertex(50.0, 50.0, Some(20.0)), vertex(50.0, 10.0, Some(20.0))];
        let mut hf = Heightfield::flat(101, 101, 1.0, 0.0);
        bulldoze(&mut hf, path(), blade(10.0, &[[-1.0, 20.0], [1.0, 20.0]]), Operator::Replace);
        for (dx, dz) in [(3, 3), (1, 4), (4, 1), (0, 5), (5, 0)] {
            assert_eq!(hf.get(50 + dx, 50 + dz), 40.0, "({dx}, {dz}) from the vertex");
        }
        assert_eq!(hf.get(54, 54), 0.0, "beyond the blade's reach");

        // A blade held off to the right (outside the bend), falling away 1 in 2: the pivot
        // turns it into a conical corner, h − ρ/2 at distance ρ from the vertex.
        let mut side = blade(30.0, &[[-1.0, 0.0], [1.0, -15.0]]);
        side.offset_m = 15.0;
        let mut hf = Heightfield::flat(101, 101, 1.0, 0.0);
        bulldoze(&mut hf, path(), side, Operator::Replace);
        for (dx, dz) in [(10, 10), (3, 20), (20, 3), (15, 15), (1, 1)] {
            let rho = ((dx * dx + dz * dz) as f64).sqrt();
            let got = hf.get(50 + dx, 50 + dz);
            assert!(close(got, 20.0 - rho / 2.0, 1e-4), "({dx}, {dz}): {got}");
        }
        assert_eq!(hf.get(72, 72), 0.0);
        // Along the straight parts the slope is as the blade's profile.
        assert!(close(hf.get(30, 60), 15.0, 1e-4) && close(hf.get(60, 30), 15.0, 1e-4));
    }

    #[test]
    fn later_moves_win_where_moves_overlap() {
        // A hairpin: the second move runs back over the first one's swath.
        let mut hf = Heightfield::flat(61, 41, 1.0, 0.0);
        let path = vec![vertex(10.0, 20.0, Some(2.0)), vertex(50.0, 20.0, Some(2.0)), vertex(10.0, 22.0, Some(4.0))];
        bulldoze(&mut hf, path, blade(6.0, &[[-1.0, 0.0], [1.0, 0.0]]), Operator::Add);
        // Under both swaths the sample takes the later move's relief once (0 m here), never
        // twice; the point is that `add` with a flat blade leaves the surface where it was.
        assert!(hf.heights_m.iter().all(|&h| h == 0.0));

        let mut hf = Heightfield::flat(61, 41, 1.0, 0.0);
        let path = vec![vertex(10.0, 20.0, Some(2.0)), vertex(50.0, 20.0, Some(2.0)), vertex(10.0, 22.0, Some(4.0))];
        bulldoze(&mut hf, path, blade(6.0, &[[-1.0, 0.0], [1.0, 0.0]]), Operator::Replace);
        // (30, 20) lies under both moves: the return move, at height ≈ 3 there, stands.
        assert!(close(hf.get(30, 20), 3.0, 0.06), "{}", hf.get(30, 20));
        // (30, 17) only under the first move.
        assert_eq!(hf.get(30, 17), 2.0);
    }

    #[test]
    fn offset_shifts_the_swath_to_the_right_of_travel() {
        let v_shape = [[-1.0, 0.0], [0.0, -1.0], [1.0, 0.0]];
        let mut b = blade(8.0, &v_shape);
        b.offset_m = 3.0;
        let mut hf = Heightfield::flat(81, 61, 1.0, 10.0);
        bulldoze(
            &mut hf,
            vec![vertex(20.0, 30.0, Some(10.0)), vertex(60.0, 30.0, Some(10.0))],
            b.clone(),
            Operator::Replace,
        );
        // Travelling +X, right is +Z: the swath spans z 29..37 with its lowest point at z 33.
        let column: Vec<f32> = (0..61).map(|r| hf.get(40, r)).collect();
        assert_eq!(column[33], 9.0);
        assert_eq!(column[28], 10.0);
        assert!(close(column[29], 10.0, 1e-6) && close(column[37], 10.0, 1e-6));
        assert!(close(column[31], 9.5, 1e-6) && close(column[35], 9.5, 1e-6));

        // Travelling −X the same offset lands on the other side.
        let mut hf = Heightfield::flat(81, 61, 1.0, 10.0);
        bulldoze(&mut hf, vec![vertex(60.0, 30.0, Some(10.0)), vertex(20.0, 30.0, Some(10.0))], b, Operator::Replace);
        assert_eq!(hf.get(40, 27), 9.0);
    }

    #[test]
    fn angle_skews_the_swath_as_documented() {
        let mut b = blade(10.0, &[[-1.0, 5.0], [1.0, 5.0]]);
        b.angle_deg = 30.0;
        let mut hf = Heightfield::flat(81, 61, 1.0, 0.0);
        bulldoze(&mut hf, vec![vertex(20.0, 30.0, Some(0.0)), vertex(60.0, 30.0, Some(0.0))], b, Operator::Replace);
        // A point d across lies on the blade at a = d / cos 30°, reached when the centre is at
        // s0 = s − a sin 30°: at d = +4 (z = 34) the swath covers x ∈ [22.31, 62.31], at
        // d = −4 (z = 26) x ∈ [17.69, 57.69]; |d| ≤ 5 cos 30° = 4.33.
        let changed = |x: usize, z: usize| hf.get(x, z) == 5.0;
        assert!(!changed(22, 34) && changed(23, 34) && changed(62, 34) && !changed(63, 34));
        assert!(!changed(17, 26) && changed(18, 26) && changed(57, 26) && !changed(58, 26));
        assert!(changed(40, 34) && !changed(40, 35) && changed(40, 26) && !changed(40, 25));
    }

    /// The pass as §2.4 states it, sample by sample: each move in turn writes its
    /// combination with the pass-start surface over its bounds.
    fn naive_pass(start: &Heightfield, moves: &[MoveStep], window: Option<&Window>) -> Heightfield {
        let mut out = start.clone();
        let cell = start.cell_size_m as f64;
        let in_window = |x: f64, z: f64| {
            window.is_none_or(|w| {
                x >= w.min_x as f64 && x <= w.max_x as f64 && z >= w.min_z as f64 && z <= w.max_z as f64
            })
        };
        for step in moves {
            let g = MoveGeometry::new(step, Some(start));
            for row in 0..start.rows {
                for col in 0..start.cols {
                    let (x, z) = (col as f64 * cell, row as f64 * cell);
                    if !in_window(x, z) || !g.bounds.contains(x, z) {
                        continue;
                    }
                    if let Some((base, relief)) = g.sample(x, z) {
                        let h = step.operator.combine(start.get(col, row) as f64, base, relief);
                        out.heights_m[row * start.cols + col] = h as f32;
                    }
                }
            }
        }
        out
    }

    /// A path `n` vertices long running back and forth between x = 8 and x = 32 around z = 20.
    fn zig_zag(n: usize, height: Option<f32>) -> Vec<PathVertex> {
        (0..n).map(|i| vertex(if i % 2 == 0 { 8.0 } else { 32.0 }, 19.0 + (i % 3) as f32, height)).collect()
    }

    #[test]
    fn a_zig_zag_pass_matches_the_move_by_move_reference() {
        let start = Heightfield::from_fn(41, 41, 1.0, |x, z| 3.0 + 2.0 * (x * 0.2).sin() + 0.1 * z);
        let mut b = blade(7.0, &[[-1.0, 0.5], [-0.3, -1.5], [0.4, -1.0], [1.0, 0.8]]);
        b.offset_m = 0.7;
        b.angle_deg = 15.0;
        let window = Window { min_x: 5.0, min_z: 12.0, max_x: 30.5, max_z: 40.0 };
        for operator in [Operator::Replace, Operator::Add, Operator::Average, Operator::Max] {
            for window in [None, Some(&window)] {
                let moves = resolve_pass(
                    &start,
                    0,
                    &PassOp {
                        path: zig_zag(9, None),
                        blade: b.clone(),
                        operator,
                        keyframes: Vec::new(),
                        contour: None,
                        base: PathBase::Linear,
                    },
                );
                let mut hf = start.clone();
                apply_pass(&mut hf, &moves, window, |_| Ok::<(), ()>(())).unwrap();
                let want = naive_pass(&start, &moves, window);
                let bits = |hf: &Heightfield| hf.heights_m.iter().map(|h| h.to_bits()).collect::<Vec<_>>();
                assert!(bits(&hf) == bits(&want), "{operator:?}, window {window:?}");
                assert!(hf != start, "{operator:?}, window {window:?}: the pass changes the terrain");
            }
        }
    }

    #[test]
    fn a_long_zig_zag_over_one_spot_cuts_each_sample_once() {
        // 20 000 moves over the same few hundred samples: each overlaps all the others.
        let start = Heightfield::flat(41, 41, 1.0, 5.0);
        let mut hf = start.clone();
        let cut = blade(6.0, &[[-1.0, -1.0], [1.0, -1.0]]);
        let moves = bulldoze(&mut hf, zig_zag(20_001, Some(5.0)), cut, Operator::Add);
        assert_eq!(moves.len(), 20_000);
        let mut cut_samples = 0;
        for (a, b) in start.heights_m.iter().zip(&hf.heights_m) {
            assert!(b == a || b - a == -1.0, "changed by {}", b - a);
            cut_samples += (b != a) as usize;
        }
        assert!(cut_samples > 200, "{cut_samples}");
    }
}
