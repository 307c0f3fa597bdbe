//! From recorded rings to the sections a surface passes through: each ring widened by the
//! coating of every wet pass after it (section 3.3's horizontal growth, never more than
//! [`CLEARANCE_SHARE`] of its clearance to another site or a wall), a stalagmite's top rounded
//! by its splash, a stalactite ending in a drip tip or, while young and thin, open into its
//! central canal, and a column's join blended into a smooth waist.

use super::chamber::{rim, ChamberShape};
use super::growth::{coating_units, Ring, SiteGrowth, CLOSED_RADIUS_M};
use super::neighbours::{centres, ring_capsules, Bodies, Capsule, CLEARANCE_SHARE, MARGIN_M};
use super::params::GrowCaveParams;
use super::speleothem_mesh::{shade, End, Profile, Section};

/// Rings closer than this in height are one section (the later one kept).
const MIN_STEP_M: f32 = 1e-4;
/// A stalagmite's rounded top rises at most this many of its radii above the last ring.
const DOME_RADII: f32 = 0.6;
/// A stalactite's drip tip hangs at most this many of its radii below the last ring.
const TIP_RADII: f32 = 1.0;
/// Share of the gap between a stalactite's tip and its stalagmite's top that each may fill.
const GAP_SHARE: f32 = 0.45;
/// A hollow ring's canal is at most this share of its radius.
const CANAL_SHARE: f32 = 0.5;
/// The rings of a stalagmite's dome, degrees up its quarter circle: the last leaves a cap of
/// cos 80° ≈ 0.17 of the radius, a rounded top rather than a flat one.
const DOME_ANGLES: [f32; 3] = [30.0, 60.0, 80.0];
/// Neighbouring sections of a column differ in radius by at most this ratio (a smooth join).
const RING_RATIO: f32 = 1.08;
/// And a column narrows by at most this much radius per metre of height: the wider half
/// tapers into the narrower as a cone (an hourglass waist), not a bottle's shoulder.
const TAPER: f32 = 0.15;

/// Everything the profiles of one cave need besides the site.
pub struct Context<'a> {
    pub params: &'a GrowCaveParams,
    pub bodies: &'a Bodies,
    pub shape: &'a ChamberShape,
}

/// What a site's speleothems look like: a column, or a stalactite and a stalagmite (either may
/// be missing).
pub enum SiteProfiles {
    Column(Profile),
    Apart { stalactite: Option<Profile>, stalagmite: Option<Profile> },
}

/// Coating, metres, that the passes after pass `p` add to a ring, for every `p` from 0 to the
/// number of passes: `after[p]`. Once the site is a column (pass `column_at`) no drop falls
/// any more: one film runs down the whole column, and its stalagmite is coated as its
/// stalactite is (the paper's condition (iv), §4.1: after a column only horizontal growth).
fn coating_after(weather: &str, unit: f32, stalagmite: bool, column_at: Option<u32>) -> Vec<f32> {
    let letters: Vec<char> = weather.chars().collect();
    let mut after = vec![0.0f32; letters.len() + 1];
    for p in (0..letters.len()).rev() {
        let (t, m) = coating_units(letters[p]);
        // letters[p] is pass p + 1, still dripping when p + 1 ≤ c.
        let dripping = column_at.is_none_or(|c| (p as u32) < c);
        after[p] = after[p + 1] + unit * if stalagmite && dripping { m } else { t };
    }
    after
}

/// One speleothem's rings as sections, before its ends are shaped: the anchor inside the rock,
/// then each ring (coated, within its clearance). Also returns each section's widest allowed
/// radius.
///
/// The clearance search reaches only as far as can matter: for a column, as far as its waist
/// may widen a ring (`column` is true); otherwise as far as the ring's own coating goes.
fn ring_sections(
    ctx: &Context,
    index: u32,
    site: &SiteGrowth,
    rings: &[Ring],
    down: bool,
    column: bool,
) -> (Vec<Section>, Vec<f32>) {
    let p = ctx.params;
    let sign = if down { -1.0 } else { 1.0 };
    let base_y = if down { site.roof_y_m } else { site.floor_y_m };
    let after = coating_after(&site.weather, p.coating_share * p.radius_step_m, !down, site.column_at);
    let centres = centres(site, rings, down);
    let caps: Vec<[Capsule; 2]> = (0..rings.len()).map(|k| ring_capsules(site, rings, &centres, k, down)).collect();
    let most_coating = after.first().copied().unwrap_or(0.0) + 2.0 * rings.iter().map(Ring::radius).fold(0.0, f32::max);
    let clearance = |c: &Capsule, reach: f32| {
        ctx.bodies.gap(index, c, reach).min(c.wall_gap(p.chamber.width_m, p.chamber.depth_m)).max(0.0)
    };
    let rc = rings.len() as f32;
    let open = OpenAir::new(ctx.shape, rings, &centres, after.first().copied().unwrap_or(0.0), down);
    let mut sections = Vec::with_capacity(rings.len() + 1);
    let mut widest = Vec::with_capacity(rings.len() + 1);
    for (k, ring) in rings.iter().enumerate() {
        // A tip closed to a point stays one: the film drips from it.
        let closed = ring.radius() < CLOSED_RADIUS_M;
        let coating = if closed { 0.0 } else { after[(ring.pass() as usize).min(after.len() - 1)] };
        // Beyond coating / share the clearance cannot bind: a gap found farther is as good as none.
        let reach = if column { most_coating } else { coating } / CLEARANCE_SHARE + MIN_STEP_M;
        let mut gap = clearance(&caps[k][0], reach).min(clearance(&caps[k][1], reach));
        if let Some(next) = caps.get(k + 1) {
            gap = gap.min(clearance(&next[0], reach));
        }
        // Nor into the floor or roof.
        let limit = open.widest(centres[k], ring, ring.radius() + CLEARANCE_SHARE * gap);
        let coated = ring.radius() + coating;
        let section = |centre| Section {
            centre,
            radius: coated.min(limit),
            displacement: ring.displacement(),
            shade: shade((k + 1) as f32 / rc),
        };
        if k == 0 {
            let c = centres[0];
            let anchor = [c[0], base_y - sign * ring.radius().max(0.02), c[2]];
            sections.push(Section { displacement: 0.0, shade: shade(1.0 / rc), ..section(anchor) });
            widest.push(limit);
        }
        let s = section(centres[k]);
        let last = sections.last().expect("the anchor");
        if k > 0 && (s.centre[1] - last.centre[1]).abs() < MIN_STEP_M {
            // No height between them: one section, the later.
            sections.pop();
            widest.pop();
        }
        sections.push(s);
        widest.push(limit);
    }
    (sections, widest)
}

/// Where a speleothem's coated rings may reach: off the floor and the roof (by [`MARGIN_M`]),
/// except round its own foot — below the highest floor (above the lowest roof) under its first
/// ring as coated, where it stands in the rock.
struct OpenAir<'a> {
    shape: &'a ChamberShape,
    down: bool,
    foot_y: f32,
}

impl<'a> OpenAir<'a> {
    fn new(shape: &'a ChamberShape, rings: &[Ring], centres: &[[f32; 3]], most_coating: f32, down: bool) -> Self {
        let r = rings.first().map_or(0.0, |r| r.radius() + r.displacement()) + most_coating;
        let c = centres.first().copied().unwrap_or_default();
        let foot_y = if down {
            rim(c, r, 16).map(|(x, z)| shape.roof_y(x, z)).fold(f32::INFINITY, f32::min)
        } else {
            rim(c, r, 16).map(|(x, z)| shape.floor_y(x, z)).fold(f32::NEG_INFINITY, f32::max)
        };
        Self { shape, down, foot_y }
    }

    /// Whether a disc of radius `r` at `c` is off the rock (or in its foot).
    fn clear(&self, c: [f32; 3], r: f32) -> bool {
        let y = c[1];
        let in_foot = if self.down { y >= self.foot_y - MARGIN_M } else { y <= self.foot_y + MARGIN_M };
        rim(c, r, 16).all(|(x, z)| {
            let floor_ok = y > self.shape.floor_y(x, z) + MARGIN_M || in_foot && !self.down;
            let roof_ok = y < self.shape.roof_y(x, z) - MARGIN_M || in_foot && self.down;
            floor_ok && roof_ok
        })
    }

    /// The widest radius up to `want` a ring at `c` may take: `want` if its disc (with the
    /// ring's displacement) is clear, else found by bisection down to the ring's own radius
    /// (which growth kept clear, or which rests on the rock where the speleothem stopped).
    fn widest(&self, c: [f32; 3], ring: &Ring, want: f32) -> f32 {
        let d = ring.displacement();
        if want <= ring.radius() || self.clear(c, want + d) {
            return want;
        }
        let (mut lo, mut hi) = (ring.radius(), want);
        for _ in 0..12 {
            let mid = 0.5 * (lo + hi);
            if self.clear(c, mid + d) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo
    }
}

/// The start of a tube: a point half a radius deeper into the rock than its anchor.
fn start_apex(sections: &[Section], down: bool) -> [f32; 3] {
    let a = sections[0];
    let sign = if down { -1.0 } else { 1.0 };
    [a.centre[0], a.centre[1] - sign * a.radius.max(0.01) * 0.5, a.centre[2]]
}

/// A stalagmite's top rounded by its splash: a dome [`DOME_RADII`] of the top radius high,
/// its apex at most `room` above the last section. Short of room the dome sinks into the
/// stalagmite (the sections it covers go) rather than flattening: a top never ends in a disc.
fn dome(sections: &mut Vec<Section>, room: f32) -> End {
    let top = *sections.last().expect("sections");
    if top.radius < CLOSED_RADIUS_M {
        return End::Apex(top.centre);
    }
    let height = DOME_RADII * top.radius;
    let apex_y = top.centre[1] + height.min(room.max(0.0));
    // The foot: `height` below the apex, and above the anchor in the floor (a stalagmite
    // with no room to rise and no height of its own is a low mound, its dome half buried).
    let foot_y = (apex_y - height).max(sections[0].centre[1] + MIN_STEP_M);
    while sections.len() > 2 && sections[sections.len() - 2].centre[1] >= foot_y {
        sections.pop();
    }
    let n = sections.len() - 1;
    if n >= 1 && sections[n].centre[1] > foot_y && sections[n - 1].centre[1] < foot_y {
        // Cut the last step at the foot, its centre and radius interpolated.
        let (lo, hi) = (sections[n - 1], sections[n]);
        let t = (foot_y - lo.centre[1]) / (hi.centre[1] - lo.centre[1]);
        let l = |a: f32, b: f32| a + (b - a) * t;
        sections[n] = Section {
            centre: [l(lo.centre[0], hi.centre[0]), foot_y, l(lo.centre[2], hi.centre[2])],
            radius: l(lo.radius, hi.radius),
            ..hi
        };
    }
    let base = *sections.last().expect("sections");
    let h = apex_y - base.centre[1];
    if h < MIN_STEP_M {
        return End::Apex(base.centre);
    }
    for angle in DOME_ANGLES {
        let (sin, cos) = angle.to_radians().sin_cos();
        let centre = [base.centre[0], base.centre[1] + h * sin, base.centre[2]];
        sections.push(Section { centre, radius: base.radius * cos, ..base });
    }
    End::Apex([base.centre[0], apex_y, base.centre[2]])
}

/// A stalactite's drip tip: the last ring narrowing to a point `length` below it, concave.
fn drip_tip(sections: &mut Vec<Section>, length: f32) -> End {
    let tip = *sections.last().expect("sections");
    if length < MIN_STEP_M || tip.radius < CLOSED_RADIUS_M {
        return End::Apex(tip.centre);
    }
    for s in [1.0f32 / 3.0, 2.0 / 3.0] {
        let centre = [tip.centre[0], tip.centre[1] - length * s, tip.centre[2]];
        sections.push(Section { centre, radius: tip.radius * (1.0 - s).powf(1.5), ..tip });
    }
    End::Apex([tip.centre[0], tip.centre[1] - length, tip.centre[2]])
}

/// The canal of a free stalactite: through the sections from the tip up while each is thinner
/// than `straw_max_radius_m`, closing at the centre of the first solid one (or the anchor).
/// None when the tip is closed, solid, or canals are off.
fn canal(params: &GrowCaveParams, sections: &[Section]) -> Option<End> {
    if params.canal_radius_m <= 0.0 {
        return None;
    }
    let hollow = |s: &Section| s.radius >= CLOSED_RADIUS_M && s.radius < params.straw_max_radius_m;
    // Section 0 is the anchor, in the rock: the canal may reach it but not open there.
    let mut from = sections.len();
    while from > 1 && hollow(&sections[from - 1]) {
        from -= 1;
    }
    if from == sections.len() {
        return None;
    }
    let radii = sections[from..].iter().map(|s| params.canal_radius_m.min(CANAL_SHARE * s.radius)).collect();
    Some(End::Canal { from, radii, apex: sections[from - 1].centre })
}

/// How far apart a site's stalactite tip and stalagmite top hang (infinite when one is missing).
fn gap_between(site: &SiteGrowth) -> f32 {
    if site.stalactite.is_empty() || site.stalagmite.is_empty() {
        return f32::INFINITY;
    }
    (site.stalactite_tip_y() - site.stalagmite_top_y()).max(0.0)
}

fn stalactite(ctx: &Context, index: u32, site: &SiteGrowth) -> Profile {
    let (mut sections, _) = ring_sections(ctx, index, site, &site.stalactite, true, false);
    let start = start_apex(&sections, true);
    let end = match canal(ctx.params, &sections) {
        Some(end) => end,
        None => {
            let r = site.stalactite.last().map_or(0.0, Ring::radius);
            // Never into the floor under the tip.
            let [x, z] = site.drip_point();
            let floor = site.stalactite_tip_y() - ctx.shape.floor_y(x, z) - MIN_STEP_M;
            drip_tip(&mut sections, (TIP_RADII * r).min(GAP_SHARE * gap_between(site)).min(floor.max(0.0)))
        }
    };
    Profile { sections, down: true, start, end }
}

fn stalagmite(ctx: &Context, index: u32, site: &SiteGrowth) -> Profile {
    let (mut sections, _) = ring_sections(ctx, index, site, &site.stalagmite, false, false);
    let start = start_apex(&sections, false);
    // Within the body's tip capsule (TIP_REACH radii, widened by the coating's limit), and
    // never into the roof over the top's disc.
    let ([x, z], top_y) = (site.stalagmite_top_xz(), site.stalagmite_top_y());
    let r = sections.last().map_or(0.0, |s| s.radius + s.displacement);
    let lowest = rim([x, top_y, z], r, 16).map(|(x, z)| ctx.shape.roof_y(x, z)).fold(f32::INFINITY, f32::min);
    let roof = lowest - top_y - MIN_STEP_M;
    let end = dome(&mut sections, (GAP_SHARE * gap_between(site)).min(roof));
    Profile { sections, down: false, start, end }
}

/// A column: the stalactite down to the join, the stalagmite from there to the floor, the
/// join's radii blended over two radii above and below by a Gaussian of the profile (a smooth
/// waist instead of a step), never wider than each section's clearance allows.
fn column(ctx: &Context, index: u32, site: &SiteGrowth) -> Profile {
    let (mut sections, mut widest) = ring_sections(ctx, index, site, &site.stalactite, true, true);
    let (mut below, mut below_widest) = ring_sections(ctx, index, site, &site.stalagmite, false, true);
    below.reverse();
    below_widest.reverse();
    // The meeting rings share their height: one section at the stalactite's centre, as narrow
    // as the narrower (the waist), which the blend below widens smoothly into both.
    let join = sections.len() - 1;
    let (a, b) = (sections[join].radius, below[0].radius);
    sections[join].radius = a.min(b);
    widest[join] = widest[join].min(below_widest[0]);
    sections.extend_from_slice(&below[1..]);
    widest.extend_from_slice(&below_widest[1..]);
    let y_join = sections[join].centre[1];
    let span = 2.0 * a.max(b);
    if span > 0.0 {
        let sigma = span / 3.0;
        let near: Vec<usize> = (0..sections.len()).filter(|&k| (sections[k].centre[1] - y_join).abs() < span).collect();
        let radii: Vec<f32> = sections.iter().map(|s| s.radius).collect();
        for &k in &near {
            let y = sections[k].centre[1];
            let (mut sum, mut weight) = (0.0f64, 0.0f64);
            for (t, s) in sections.iter().enumerate() {
                let d = (s.centre[1] - y) / sigma;
                if d.abs() < 3.0 {
                    let w = (-0.5 * d as f64 * d as f64).exp();
                    sum += w * radii[t] as f64;
                    weight += w;
                }
            }
            let smooth = (sum / weight) as f32;
            let fade = 1.0 - ((y - y_join) / span).powi(2);
            let r = radii[k] + (smooth - radii[k]) * fade * fade;
            sections[k].radius = r.min(widest[k]);
        }
    }
    limit_ring_ratio(&mut sections, &widest);
    let start = start_apex(&sections, true);
    let last = *sections.last().expect("sections");
    let end = End::Apex([last.centre[0], last.centre[1] - last.radius.max(0.01) * 0.5, last.centre[2]]);
    Profile { sections, down: true, start, end }
}

/// Neighbouring sections of a column within [`RING_RATIO`] of each other, leaving out the two
/// anchors in the rock: the narrow side first flares towards the wide one within each
/// section's own limit, then wherever a limit kept a section narrow its neighbours narrow to
/// it (only lowering, so every clearance still holds), and no faster than [`TAPER`] per metre:
/// after the last two sweeps every radius is the least over j of r_j grown by the ratio and
/// the taper from j to k, so neighbours are within both.
fn limit_ring_ratio(sections: &mut [Section], widest: &[f32]) {
    let n = sections.len();
    if n < 4 {
        return;
    }
    for k in 2..n - 1 {
        let want = sections[k - 1].radius / RING_RATIO;
        if sections[k].radius < want {
            sections[k].radius = want.min(widest[k]);
        }
    }
    for k in (1..n - 2).rev() {
        let want = sections[k + 1].radius / RING_RATIO;
        if sections[k].radius < want {
            sections[k].radius = want.min(widest[k]);
        }
    }
    let bound =
        |from: &Section, y: f32| (from.radius * RING_RATIO).min(from.radius + TAPER * (from.centre[1] - y).abs());
    for k in 2..n - 1 {
        sections[k].radius = sections[k].radius.min(bound(&sections[k - 1], sections[k].centre[1]));
    }
    for k in (1..n - 2).rev() {
        sections[k].radius = sections[k].radius.min(bound(&sections[k + 1], sections[k].centre[1]));
    }
}

/// The profiles of site `index`.
pub fn site_profiles(ctx: &Context, index: u32, site: &SiteGrowth) -> SiteProfiles {
    if site.column_at.is_some() {
        return SiteProfiles::Column(column(ctx, index, site));
    }
    SiteProfiles::Apart {
        stalactite: (!site.stalactite.is_empty()).then(|| stalactite(ctx, index, site)),
        stalagmite: (!site.stalagmite.is_empty()).then(|| stalagmite(ctx, index, site)),
    }
}
