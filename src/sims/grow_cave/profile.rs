//! From recorded rings to the sections a surface passes through: each ring widened by the
//! coating of every wet pass after it (section 3.3's horizontal growth, never more than
//! [`CLEARANCE_SHARE`] of its clearance to another site or a wall), a stalagmite's top rounded
//! by its splash, a stalactite ending in a drip tip or, while young and thin, open into its
//! central canal, and a column's join blended into a smooth waist.

use super::growth::{coating_units, Ring, SiteGrowth, CLOSED_RADIUS_M};
use super::neighbours::{centres, ring_capsules, Bodies, Capsule, CLEARANCE_SHARE};
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

/// Everything the profiles of one cave need besides the site.
pub struct Context<'a> {
    pub params: &'a GrowCaveParams,
    pub bodies: &'a Bodies,
}

/// What a site's speleothems look like: a column, or a stalactite and a stalagmite (either may
/// be missing).
pub enum SiteProfiles {
    Column(Profile),
    Apart { stalactite: Option<Profile>, stalagmite: Option<Profile> },
}

/// Coating, metres, that the passes after pass `p` add to a ring, for every `p` from 0 to the
/// number of passes: `after[p]`.
fn coating_after(weather: &str, unit: f32, stalagmite: bool) -> Vec<f32> {
    let letters: Vec<char> = weather.chars().collect();
    let mut after = vec![0.0f32; letters.len() + 1];
    for p in (0..letters.len()).rev() {
        let (t, m) = coating_units(letters[p]);
        after[p] = after[p + 1] + unit * if stalagmite { m } else { t };
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
    let after = coating_after(&site.weather, p.coating_share * p.radius_step_m, !down);
    let centres = centres(site, rings, down);
    let caps: Vec<[Capsule; 2]> = (0..rings.len()).map(|k| ring_capsules(site, rings, &centres, k, down)).collect();
    let most_coating = after.first().copied().unwrap_or(0.0) + 2.0 * rings.iter().map(Ring::radius).fold(0.0, f32::max);
    let clearance = |c: &Capsule, reach: f32| {
        ctx.bodies.gap(index, c, reach).min(c.wall_gap(p.chamber.width_m, p.chamber.depth_m)).max(0.0)
    };
    let rc = rings.len() as f32;
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
        let limit = ring.radius() + CLEARANCE_SHARE * gap;
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

/// The start of a tube: a point half a radius deeper into the rock than its anchor.
fn start_apex(sections: &[Section], down: bool) -> [f32; 3] {
    let a = sections[0];
    let sign = if down { -1.0 } else { 1.0 };
    [a.centre[0], a.centre[1] - sign * a.radius.max(0.01) * 0.5, a.centre[2]]
}

/// A stalagmite's top rounded by its splash: two rings of a dome `height` above the last and
/// its top.
fn dome(sections: &mut Vec<Section>, height: f32) -> End {
    let top = *sections.last().expect("sections");
    if height < MIN_STEP_M || top.radius < CLOSED_RADIUS_M {
        return End::Apex(top.centre);
    }
    for angle in [30f32, 60.0] {
        let (sin, cos) = angle.to_radians().sin_cos();
        let centre = [top.centre[0], top.centre[1] + height * sin, top.centre[2]];
        sections.push(Section { centre, radius: top.radius * cos, ..top });
    }
    End::Apex([top.centre[0], top.centre[1] + height, top.centre[2]])
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
            drip_tip(&mut sections, (TIP_RADII * r).min(GAP_SHARE * gap_between(site)))
        }
    };
    Profile { sections, down: true, start, end }
}

fn stalagmite(ctx: &Context, index: u32, site: &SiteGrowth) -> Profile {
    let (mut sections, _) = ring_sections(ctx, index, site, &site.stalagmite, false, false);
    let start = start_apex(&sections, false);
    // Within the body's tip capsule (TIP_REACH radii, widened by the coating's limit).
    let top = sections.last().expect("sections").radius;
    let end = dome(&mut sections, (DOME_RADII * top).min(GAP_SHARE * gap_between(site)));
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
    let start = start_apex(&sections, true);
    let last = *sections.last().expect("sections");
    let end = End::Apex([last.centre[0], last.centre[1] - last.radius.max(0.01) * 0.5, last.centre[2]]);
    Profile { sections, down: true, start, end }
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
