//! Ring-by-ring growth (paper section 4.1, Table 2): each pass, every growing speleothem gets a
//! new ring whose radius and height step follow the pluviometric index level, the drip
//! interval and the CO₂ concentration; wind displaces it; low CO₂ adds horizontal
//! displacement vd = kf · arr / irr. Growth stops under the paper's four conditions.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::chamber::{rim, ChamberShape};
use super::params::{Co2, Conditions, DripInterval, GrowCaveParams, ManualRing, Pluviometric};

/// Radii below this close the tip (condition ii: the new ring's radius is zero).
pub const CLOSED_RADIUS_M: f32 = 1e-4;
/// A stalactite's tip and its stalagmite's top join into a column only when this close
/// horizontally (the same point, to rounding).
const ALIGNED_M: f32 = 1e-4;

/// One ring as grown: `[pass, [radius_m, height_m, dx_m, dz_m, vd_m]]` — the pass that grew
/// it, its radius, its vertical step from the ring before, the wind's horizontal shift of its
/// centre from the ring before, and the horizontal displacement of its surface.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Ring(pub u32, pub [f32; 5]);

impl Ring {
    pub fn pass(&self) -> u32 {
        self.0
    }
    pub fn radius(&self) -> f32 {
        self.1[0]
    }
    pub fn height(&self) -> f32 {
        self.1[1]
    }
    pub fn shift(&self) -> [f32; 2] {
        [self.1[2], self.1[3]]
    }
    pub fn displacement(&self) -> f32 {
        self.1[4]
    }
    /// Keep `share` of the ring's growth: its height and the wind's shift alike (the shift is
    /// made in proportion to the height, so a ring cut short leans as its whole would).
    fn trim(&mut self, share: f32) {
        let share = share.clamp(0.0, 1.0);
        for v in &mut self.1[1..4] {
            *v *= share;
        }
    }
}

/// The conditions one ring grows under.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Drawn {
    pub level: u8,
    pub drip: DripInterval,
    pub co2: Co2,
}

impl Drawn {
    /// The pass's letter in [`SiteGrowth::weather`].
    fn letter(&self) -> char {
        match (self.level, self.drip) {
            (0, _) => '0',
            (1, _) => '1',
            (_, DripInterval::Dry) => 'd',
            (_, DripInterval::Wet) => 'w',
            _ => 's',
        }
    }
}

/// How much water coats a stalactite (`.0`) and a stalagmite (`.1`) in a pass of `weather`
/// letter `c`, in `coating_share × radius_step_m` units: a thin film runs over a stalactite
/// whenever it rains (half a unit); only a drip splashes a stalagmite, half a unit at a dry
/// interval, one at a standard, 2.5 at a wet
/// (so that by default a wet stalagmite's older rings widen faster than Table 2 widens its
/// new ones, and its base ends wider than its top).
pub fn coating_units(c: char) -> (f32, f32) {
    match c {
        '1' => (0.5, 0.0),
        'd' => (0.5, 0.5),
        's' => (0.5, 1.0),
        'w' => (0.5, 2.5),
        _ => (0.0, 0.0),
    }
}

/// Table 2: (radius direction × multiple, height multiple) of a stalactite at `co2`.
pub fn stalactite_row(co2: Co2) -> (i32, u32) {
    match co2 {
        Co2::Low => (-2, 1),
        Co2::Normal => (-1, 2),
        Co2::High | Co2::Random => (0, 3),
    }
}

/// Table 2: (radius direction × multiple, height multiple) of a stalagmite.
pub fn stalagmite_row(drip: DripInterval, co2: Co2) -> (i32, u32) {
    let radius = match drip {
        DripInterval::Dry => -1,
        DripInterval::Standard | DripInterval::Random | DripInterval::Pluviometric => 0,
        DripInterval::Wet => 1,
    };
    let height = match co2 {
        Co2::Low => 1,
        Co2::Normal => 2,
        Co2::High | Co2::Random => 3,
    };
    (radius, height)
}

/// A drip site as it grows: the recorded rings of its stalactite and stalagmite.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SiteGrowth {
    pub x_m: f32,
    pub z_m: f32,
    pub roof_y_m: f32,
    pub floor_y_m: f32,
    /// Ring 0 is the initial calcite ring.
    pub stalactite: Vec<Ring>,
    pub stalagmite: Vec<Ring>,
    /// The pass at which the two met and became a column.
    pub column_at: Option<u32>,
    /// The weather of every pass so far, a letter each: `0` no rain, `1` rain without
    /// dripping, `d` / `s` / `w` dripping at a dry, standard or wet interval. The coating
    /// (horizontal growth) of every ring is read from it.
    #[serde(default)]
    pub weather: String,
    /// The earlier drip site this one joined at the start (their initial rings would overlap):
    /// its water runs with that site's and it grows nothing of its own.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub merged_into: Option<u32>,
    #[serde(skip)]
    pub stalactite_done: bool,
    #[serde(skip)]
    pub stalagmite_done: bool,
}

impl SiteGrowth {
    pub fn new(x_m: f32, z_m: f32, roof_y_m: f32, floor_y_m: f32) -> Self {
        Self {
            x_m,
            z_m,
            roof_y_m,
            floor_y_m,
            stalactite: Vec::new(),
            stalagmite: Vec::new(),
            column_at: None,
            weather: String::new(),
            merged_into: None,
            stalactite_done: false,
            stalagmite_done: false,
        }
    }

    /// Lowest point of the stalactite's axis.
    pub fn stalactite_tip_y(&self) -> f32 {
        self.roof_y_m - self.stalactite.iter().map(Ring::height).sum::<f32>()
    }

    /// Highest point of the stalagmite's axis.
    pub fn stalagmite_top_y(&self) -> f32 {
        self.floor_y_m + self.stalagmite.iter().map(Ring::height).sum::<f32>()
    }

    /// Where the stalactite's tip hangs, (x, z): the drip site moved by every ring's wind shift.
    /// Drops fall from here.
    pub fn drip_point(&self) -> [f32; 2] {
        axis_end(self.x_m, self.z_m, &self.stalactite)
    }

    /// Where the stalagmite's top stands, (x, z).
    pub fn stalagmite_top_xz(&self) -> [f32; 2] {
        axis_end(self.x_m, self.z_m, &self.stalagmite)
    }

    pub fn growing(&self) -> bool {
        self.column_at.is_none() && !(self.stalactite_done && (self.stalagmite_done || self.stalagmite.is_empty()))
    }

    /// The site as it was after `passes` passes.
    pub fn until(&self, passes: u32) -> SiteGrowth {
        let keep = |rings: &[Ring]| rings.iter().copied().take_while(|r| r.pass() <= passes).collect();
        SiteGrowth {
            stalactite: keep(&self.stalactite),
            stalagmite: keep(&self.stalagmite),
            column_at: self.column_at.filter(|&p| p <= passes),
            weather: self.weather.chars().take(passes as usize).collect(),
            ..self.clone()
        }
    }
}

impl SiteGrowth {
    /// Put a stalagmite ring grown in `pass` where the drops land: under the stalactite's tip
    /// as it hangs now (the wind moves the drip point, not the stalagmite).
    pub fn place_under_drip(&mut self, pass: u32) {
        let drip = self.drip_point();
        let Some(last) = self.stalagmite.last().filter(|r| r.pass() == pass).copied() else { return };
        let top = self.stalagmite_top_xz();
        let before = [top[0] - last.shift()[0], top[1] - last.shift()[1]];
        let last = self.stalagmite.last_mut().expect("a ring");
        last.1[2] = drip[0] - before[0];
        last.1[3] = drip[1] - before[1];
    }
}

fn axis_end(x: f32, z: f32, rings: &[Ring]) -> [f32; 2] {
    rings.iter().fold([x, z], |[x, z], r| [x + r.shift()[0], z + r.shift()[1]])
}

/// Everything a pass needs besides the site: the request's numbers and the chamber.
pub struct Grower<'a> {
    pub params: &'a GrowCaveParams,
    pub conditions: Conditions,
    pub shape: &'a ChamberShape,
}

impl Grower<'_> {
    /// This pass's conditions; `weather` is the site's letters of the passes before.
    fn draw(&self, rng: &mut ChaCha8Rng, weather: &str) -> Drawn {
        let c = self.conditions;
        let level = match c.pluviometric_index {
            Pluviometric::Level0 => 0,
            Pluviometric::Level1 => 1,
            Pluviometric::Level2 => 2,
            Pluviometric::Random => rng.random_range(0..3),
        };
        let drip = match c.drip_interval {
            DripInterval::Random => {
                [DripInterval::Dry, DripInterval::Standard, DripInterval::Wet][rng.random_range(0..3)]
            }
            DripInterval::Pluviometric => {
                // Inversely proportional to the rain: dripping passes among the last three.
                let dripping = |c: char| matches!(c, 'd' | 's' | 'w');
                let earlier = weather.chars().rev().take(2).filter(|&c| dripping(c)).count();
                match earlier + (level == 2) as usize {
                    3 => DripInterval::Wet,
                    2 => DripInterval::Standard,
                    _ => DripInterval::Dry,
                }
            }
            d => d,
        };
        let co2 = match c.co2 {
            Co2::Random => [Co2::Low, Co2::Normal, Co2::High][rng.random_range(0..3)],
            c => c,
        };
        Drawn { level, drip, co2 }
    }

    /// One new ring of radius `previous` changed by `row`, with its height, wind shift and
    /// displacement. `manual` replaces the sampled radius and height.
    #[allow(clippy::too_many_arguments)]
    fn ring(
        &self,
        rng: &mut ChaCha8Rng,
        pass: u32,
        previous: f32,
        initial: f32,
        row: (i32, u32),
        co2: Co2,
        manual: Option<(f32, f32)>,
    ) -> Ring {
        let p = self.params;
        // Every ring draws the same numbers whatever its row, so the stream stays aligned.
        let (u_r, u_h): (f32, f32) = (rng.random_range(0.5..1.5), rng.random_range(0.5..1.5));
        let (wind_angle, wind_draw): (f32, f32) = (rng.random_range(0.0..std::f32::consts::TAU), rng.random());
        let (radius, height) = match manual {
            Some(m) => m,
            None => ((previous + row.0 as f32 * p.radius_step_m * u_r).max(0.0), row.1 as f32 * p.height_step_m * u_h),
        };
        let (dx, dz) = match &p.wind {
            Some(w) => {
                let intensity = w.intensity.unwrap_or(wind_draw);
                let dir = match w.direction {
                    Some([x, z]) => {
                        let len = (x * x + z * z).sqrt();
                        [x / len, z / len]
                    }
                    None => [wind_angle.cos(), wind_angle.sin()],
                };
                let d = intensity * w.scale * height;
                (dir[0] * d, dir[1] * d)
            }
            None => (0.0, 0.0),
        };
        // vd = kf · arr / irr: full at low CO₂ (drops solidify on the body), a slight roughness
        // otherwise.
        let share = if co2 == Co2::Low { 1.0 } else { 0.25 };
        let vd = share * p.kf_m * radius / initial;
        Ring(pass, [radius, height, dx, dz, vd])
    }

    /// Grow `site` by one pass (number `pass`, from 1): draw and record the pass's weather,
    /// then add a ring to each speleothem still growing vertically. The caller checks the new
    /// rings against the neighbours, then calls [`Grower::check_limits`].
    pub fn pass(&self, site: &mut SiteGrowth, rng: &mut ChaCha8Rng, pass: u32) {
        if site.merged_into.is_some() {
            return;
        }
        let drawn = self.draw(rng, &site.weather);
        site.weather.push(drawn.letter());
        if !site.growing() {
            return;
        }
        if drawn.level == 0 {
            return; // condition (i): no rain, no growth this pass
        }
        let p = self.params;
        let manual = p.manual.as_ref();
        if !site.stalactite_done {
            let list = manual.map(|m| m.stalactite.as_slice());
            let row = stalactite_row(drawn.co2);
            let (rings, done) = (&mut site.stalactite, &mut site.stalactite_done);
            self.extend(rng, pass, rings, done, p.stalactite_radius_m, list, row, drawn.co2, true);
        }
        if drawn.level == 2 && !site.stalagmite_done {
            let list = manual.map(|m| m.stalagmite.as_slice());
            let row = stalagmite_row(drawn.drip, drawn.co2);
            // The stalagmite grows where the drops land: under the stalactite's tip as it hangs
            // now (the wind moves the drip point, not the stalagmite).
            let (rings, done) = (&mut site.stalagmite, &mut site.stalagmite_done);
            self.extend(rng, pass, rings, done, p.stalagmite_radius_m, list, row, drawn.co2, false);
            site.place_under_drip(pass);
        }
    }

    /// Add one ring to a speleothem: its initial ring first, then one by `row` (or the manual
    /// list, whose end stops it); a stalactite (`never_widen`) keeps within the previous radius.
    #[allow(clippy::too_many_arguments)]
    fn extend(
        &self,
        rng: &mut ChaCha8Rng,
        pass: u32,
        rings: &mut Vec<Ring>,
        done: &mut bool,
        initial: f32,
        manual: Option<&[ManualRing]>,
        row: (i32, u32),
        co2: Co2,
        never_widen: bool,
    ) {
        let Some(last) = rings.last() else {
            rings.push(Ring(pass, [initial, 0.0, 0.0, 0.0, 0.0]));
            return;
        };
        let k = rings.len() - 1;
        let given = manual.filter(|m| !m.is_empty()).map(|m| m.get(k).map(|r| (r.radius_m, r.height_m)));
        if let Some(None) = given {
            *done = true; // the manual list is used up
            return;
        }
        let previous = last.radius();
        let mut ring = self.ring(rng, pass, previous, initial, row, co2, given.flatten());
        if never_widen {
            ring.1[0] = ring.1[0].min(previous);
        }
        rings.push(ring);
        if ring.radius() < CLOSED_RADIUS_M {
            *done = true; // condition (ii)
        }
    }

    /// Conditions (iii) and (iv): a speleothem reaching the floor or roof stops; a stalactite
    /// meeting its stalagmite joins it into a column at the point where they meet.
    pub fn check_limits(&self, site: &mut SiteGrowth, pass: u32) {
        // The floor and the roof where the new step runs, not only under the site: the wind
        // carries a tip over humps and hollows. The tip stops where its disc first touches —
        // before it can meet its partner, so a step that meets it has not crossed a hump.
        let shape = self.shape;
        if site.stalactite.last().is_some_and(|r| r.pass() == pass && r.height() > 0.0) {
            let c = super::neighbours::centres(site, &site.stalactite, true);
            let (a, b) = (c[c.len().saturating_sub(2)], c[c.len() - 1]);
            let r = site.stalactite.last().map_or(0.0, |r| r.radius() + r.displacement());
            if let Some(t) = first_contact(a, b, |p| rim(p, r, 8).any(|(x, z)| p[1] <= shape.floor_y(x, z))) {
                site.stalactite.last_mut().expect("a ring").trim(t);
                site.stalactite_done = true;
                // The drip point moved back with the trimmed shift: so do this pass's drops.
                site.place_under_drip(pass);
            }
        }
        if site.stalagmite.last().is_some_and(|r| r.pass() == pass && r.height() > 0.0) {
            let c = super::neighbours::centres(site, &site.stalagmite, false);
            let (a, b) = (c[c.len().saturating_sub(2)], c[c.len() - 1]);
            let r = site.stalagmite.last().map_or(0.0, |r| r.radius() + r.displacement());
            if let Some(t) = first_contact(a, b, |p| rim(p, r, 8).any(|(x, z)| p[1] >= shape.roof_y(x, z))) {
                site.stalagmite.last_mut().expect("a ring").trim(t);
                site.stalagmite_done = true;
            }
        }
        let tip = site.stalactite_tip_y();
        let top = site.stalagmite_top_y();
        if !site.stalagmite.is_empty() && !site.stalactite.is_empty() && tip <= top {
            // They met during this pass (they never overlap after one): take the overlap from
            // this pass's rings of both, in proportion to their steps, so they meet exactly and
            // no ring of an earlier pass changes (a replay until k is a run of k passes).
            let overlap = top - tip;
            let grown: f32 =
                site.stalactite.iter().chain(&site.stalagmite).filter(|r| r.pass() == pass).map(Ring::height).sum();
            if grown > 0.0 {
                let keep = ((grown - overlap) / grown).max(0.0);
                for r in site.stalactite.iter_mut().chain(site.stalagmite.iter_mut()).filter(|r| r.pass() == pass) {
                    r.trim(keep);
                }
                // The drip point moved back with the stalactite's trimmed shift.
                site.place_under_drip(pass);
            }
            let closed = |rings: &[Ring]| rings.last().is_some_and(|r| r.radius() < CLOSED_RADIUS_M);
            // The tip must hang over the top: a stalagmite that did not grow this pass may stand
            // where the drops fell before the wind moved the tip.
            let ([dx, dz], [tx, tz]) = (site.drip_point(), site.stalagmite_top_xz());
            let aligned = (dx - tx).hypot(dz - tz) <= ALIGNED_M;
            // A closed tip touching the other, or a tip reaching the top's height away from it,
            // only touches: both stop, no column. Otherwise the two become one column.
            if aligned && !(closed(&site.stalactite) || closed(&site.stalagmite)) {
                site.column_at = Some(pass);
            }
            site.stalactite_done = true;
            site.stalagmite_done = true;
        }
    }
}

/// The share (0 to 1) of the step from `a` to `b` before the axis first enters rock, or None
/// when it stays clear: sixteen steps along it, then bisection.
fn first_contact(a: [f32; 3], b: [f32; 3], rock: impl Fn([f32; 3]) -> bool) -> Option<f32> {
    let at = |t: f32| -> [f32; 3] { std::array::from_fn(|i| a[i] + (b[i] - a[i]) * t) };
    const STEPS: u32 = 16;
    let mut lo = 0.0f32;
    for i in 1..=STEPS {
        let t = i as f32 / STEPS as f32;
        if rock(at(t)) {
            let mut hi = t;
            for _ in 0..24 {
                let m = 0.5 * (lo + hi);
                if rock(at(m)) {
                    hi = m;
                } else {
                    lo = m;
                }
            }
            return Some(lo);
        }
        lo = t;
    }
    None
}

/// The RNG stream of drip site `index`: the same numbers whatever thread grows it.
pub fn site_rng(seed: u64, index: usize) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(index as u64 + 1);
    rng
}
