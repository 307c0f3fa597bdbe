//! A lit picture of a scene a person can judge: orthographic software rasterisation with a
//! z-buffer, smooth Lambert shading, a sky gradient and a soft shadow on the ground.
//!
//! The camera looks at the scene's bounds from `azimuth_deg` around Y (0 = from the +Z side,
//! looking along −Z; 90 = from +X) and `elevation_deg` above the horizon; the sun stands at the
//! picture's upper left, above and a little in front of the scene. Light is computed in linear
//! RGB and written as sRGB bytes.

use std::sync::OnceLock;

use rayon::prelude::*;

use super::scale_bar::{draw_corner_label, metres_text};
use super::srgb::srgb_to_linear;
use crate::mesh::{MaterialKind, Scene};
use crate::stop::{Stop, Stopped};

/// A camera for [`render_png`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    pub width_px: u32,
    pub height_px: u32,
    /// degrees, camera direction around Y (0 = looking along -Z from +Z side)
    pub azimuth_deg: f32,
    /// degrees above the horizon
    pub elevation_deg: f32,
}

/// Share of the picture's width and height left empty on each side around the scene's bounds.
const MARGIN: f32 = 0.08;
/// Rows rendered together by one task; each band owns its z-buffer.
pub(super) const BAND_ROWS: usize = 16;
/// Sky colour at the top and bottom rows, sRGB.
const SKY_TOP: [u8; 3] = [118, 158, 206];
const SKY_BOTTOM: [u8; 3] = [224, 231, 238];
/// Surfaces without a colour of their own.
const DEFAULT_SRGB: [u8; 3] = [200, 200, 200];
/// The glb writer's water colour.
const WATER_SRGB: [u8; 3] = [30, 90, 140];
const GROUND_SRGB: [u8; 3] = [178, 170, 152];
/// Light from the sky reaching every surface (more on upward-facing ones) and the sun's share.
const AMBIENT: f32 = 0.22;
const SKY_FILL: f32 = 0.1;
const SUN: f32 = 0.8;
/// Cells a side of the ground's shadow mask, and the box-blur radius (in cells) softening it.
const SHADOW_CELLS: usize = 256;
const SHADOW_BLUR: usize = 3;
/// Fraction of sunlight the shadow takes away from the ground.
const SHADOW_STRENGTH: f32 = 0.75;

/// Render the scene's nodes (vertex colours if present, else the material's colour; light grey
/// default) with orthographic projection framing the scene's bounds with a margin, z-buffer,
/// Lambert from a sun at upper-left plus ambient and a sky-gradient background, and a soft
/// ground shadow/plane at the lowest y if cheap; returns an 8-bit RGB PNG. An empty scene gives
/// the background only. Same bytes on any thread count.
///
/// The ground is a plane at the scene's lowest y that fades out around the scene's footprint;
/// it shows only when looking down (elevation above zero). Nodes whose mesh fails
/// [`Mesh::check`](crate::mesh::Mesh::check) are skipped. A zero width or height is taken as 1.
///
/// Looks at `stop` before each band of rows and answers `Err(Stopped)` once it is raised.
pub fn render_png(scene: &Scene, view: &View, stop: Stop) -> Result<Vec<u8>, Stopped> {
    render_png_framed(scene, view, None, stop)
}

/// As [`render_png`], framing `focus` (world bounds, min and max corner) when given rather than
/// the whole scene — the part a person should see, such as a coastline in a wide sea; what lies
/// outside is cut off by the picture's edges. The corner label gives the framed extent.
pub fn render_png_framed(
    scene: &Scene,
    view: &View,
    focus: Option<([f32; 3], [f32; 3])>,
    stop: Stop,
) -> Result<Vec<u8>, Stopped> {
    let (w, h) = (view.width_px.max(1) as usize, view.height_px.max(1) as usize);
    let camera = Camera::new(view);
    let geometry = Geometry::gather(scene);
    let background = sky_rows(h);
    let mut rgb = vec![0u8; w * h * 3];
    // The extent in metres (x × z × height) for the corner label, where there is anything.
    let extent = match geometry.bounds() {
        None => {
            rgb.par_chunks_mut(w * 3).zip(&background).for_each(|(row, sky)| {
                for px in row.chunks_exact_mut(3) {
                    px.copy_from_slice(sky);
                }
            });
            None
        }
        Some(bounds) => {
            let (lo, hi) = focus.unwrap_or(bounds);
            let extent = format!(
                "{} x {} x {} m",
                metres_text(hi[0] - lo[0]),
                metres_text(hi[2] - lo[2]),
                metres_text(hi[1] - lo[1])
            );
            let frame = Frame::new(&camera, (lo, hi), w, h);
            let screen: Vec<[f32; 3]> = geometry.positions.par_iter().map(|&p| frame.project(&camera, p)).collect();
            stop.check()?;
            let bands = bin_triangles(&geometry.indices, &screen, w, h);
            stop.check()?;
            let ground = Ground::new(&camera, &frame, &geometry, bounds);
            stop.check()?;
            let to_srgb = linear_to_srgb_table();
            rgb.par_chunks_mut(w * 3 * BAND_ROWS).zip(&bands).enumerate().for_each(|(band, (out, triangles))| {
                if stop.requested() {
                    return;
                }
                let y0 = band * BAND_ROWS;
                let rows = out.len() / (w * 3);
                let hits = rasterize_band(triangles, &geometry.indices, &screen, w, y0, rows);
                for (i, hit) in hits.iter().enumerate() {
                    let (x, y) = (i % w, y0 + i / w);
                    let px = &mut out[i * 3..i * 3 + 3];
                    let linear = match hit {
                        Some(hit) => shade(&geometry, &camera, hit),
                        None => match ground.as_ref().and_then(|g| g.at_pixel(&camera, &frame, x, y)) {
                            Some((color, weight)) => {
                                let sky = background[y].map(srgb_to_linear);
                                std::array::from_fn(|k| sky[k] + (color[k] - sky[k]) * weight)
                            }
                            None => {
                                px.copy_from_slice(&background[y]);
                                continue;
                            }
                        },
                    };
                    for k in 0..3 {
                        px[k] = to_srgb[(linear[k].clamp(0.0, 1.0) * (LUT_SIZE - 1) as f32).round() as usize];
                    }
                }
            });
            Some(extent)
        }
    };
    stop.check()?;
    if let Some(extent) = extent {
        draw_corner_label(&mut rgb, w, h, &extent);
    }
    Ok(encode_png(&rgb, w as u32, h as u32))
}

/// Orthonormal camera axes in world coordinates and the sun's direction.
struct Camera {
    right: [f32; 3],
    up: [f32; 3],
    /// Unit vector from the scene towards the camera.
    back: [f32; 3],
    /// Unit vector towards the sun.
    sun: [f32; 3],
}

impl Camera {
    fn new(view: &View) -> Self {
        let (az, el) = (view.azimuth_deg.to_radians(), view.elevation_deg.clamp(-90.0, 90.0).to_radians());
        let back = [az.sin() * el.cos(), el.sin(), az.cos() * el.cos()];
        // Kept horizontal so the picture never rolls, even looking straight down.
        let right = [az.cos(), 0.0, -az.sin()];
        let up = cross(back, right);
        let sun: [f32; 3] = std::array::from_fn(|k| -0.5 * right[k] + 0.5 * up[k] + 0.3 * back[k] + [0.0, 0.6, 0.0][k]);
        Self { right, up, back, sun: normalize(sun) }
    }
}

/// Where the view plane maps onto pixels: the projected bounds centred, scaled to fit.
struct Frame {
    center: [f32; 2],
    px_per_m: f32,
    half_size: [f32; 2],
}

impl Frame {
    fn new(camera: &Camera, (lo, hi): ([f32; 3], [f32; 3]), w: usize, h: usize) -> Self {
        let (mut min, mut max) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
        for corner in 0..8 {
            let p = [0, 1, 2].map(|k| if corner >> k & 1 == 1 { hi[k] } else { lo[k] });
            let uv = [dot(p, camera.right), dot(p, camera.up)];
            for k in 0..2 {
                min[k] = min[k].min(uv[k]);
                max[k] = max[k].max(uv[k]);
            }
        }
        let size = [w as f32, h as f32];
        let fit = |k: usize| size[k] * (1.0 - 2.0 * MARGIN) / (max[k] - min[k]);
        let px_per_m = match (fit(0).is_finite(), fit(1).is_finite()) {
            (true, true) => fit(0).min(fit(1)),
            (true, false) => fit(0),
            (false, true) => fit(1),
            (false, false) => 1.0,
        };
        Self {
            center: [(min[0] + max[0]) / 2.0, (min[1] + max[1]) / 2.0],
            px_per_m,
            half_size: [size[0] / 2.0, size[1] / 2.0],
        }
    }

    /// Pixel x, pixel y (down) and depth (metres away from the camera) of a world point.
    fn project(&self, camera: &Camera, p: [f32; 3]) -> [f32; 3] {
        [
            self.half_size[0] + (dot(p, camera.right) - self.center[0]) * self.px_per_m,
            self.half_size[1] - (dot(p, camera.up) - self.center[1]) * self.px_per_m,
            -dot(p, camera.back),
        ]
    }

    /// View-plane coordinates (along right and up, metres) of a pixel's centre.
    fn unproject(&self, x: usize, y: usize) -> [f32; 2] {
        [
            self.center[0] + (x as f32 + 0.5 - self.half_size[0]) / self.px_per_m,
            self.center[1] - (y as f32 + 0.5 - self.half_size[1]) / self.px_per_m,
        ]
    }
}

/// Every node's triangles in one list, with per-vertex linear albedo.
pub(super) struct Geometry {
    pub(super) positions: Vec<[f32; 3]>,
    pub(super) normals: Vec<[f32; 3]>,
    pub(super) albedo: Vec<[f32; 3]>,
    pub(super) indices: Vec<u32>,
}

impl Geometry {
    pub(super) fn gather(scene: &Scene) -> Self {
        let mut g = Geometry { positions: Vec::new(), normals: Vec::new(), albedo: Vec::new(), indices: Vec::new() };
        for node in &scene.nodes {
            let mesh = &node.mesh;
            if mesh.indices.is_empty() || mesh.check().is_err() {
                continue;
            }
            let base = g.positions.len() as u32;
            let tint = match (node.material, &mesh.colors) {
                (MaterialKind::VertexColors, Some(_)) => [1.0; 3],
                (MaterialKind::VertexColors, None) => DEFAULT_SRGB.map(srgb_to_linear),
                (MaterialKind::Matte { srgb }, _) => srgb.map(srgb_to_linear),
                (MaterialKind::Water, _) => WATER_SRGB.map(srgb_to_linear),
            };
            g.positions.extend_from_slice(&mesh.positions);
            g.normals.extend_from_slice(&mesh.normals);
            match &mesh.colors {
                Some(colors) => g.albedo.extend(colors.iter().map(|c| {
                    let c = [c[0], c[1], c[2]].map(srgb_to_linear);
                    std::array::from_fn(|k| c[k] * tint[k])
                })),
                None => g.albedo.extend(std::iter::repeat_n(tint, mesh.positions.len())),
            }
            g.indices.extend(mesh.indices.iter().map(|&i| base + i));
        }
        g
    }

    /// Bounds of the vertices used by triangles (all of them, for checked meshes).
    fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        let first = *self.positions.first()?;
        Some(self.positions.iter().fold((first, first), |(lo, hi), p| {
            (std::array::from_fn(|k| lo[k].min(p[k])), std::array::from_fn(|k| hi[k].max(p[k])))
        }))
    }
}

/// Triangle numbers overlapping each band of rows, in triangle order.
pub(super) fn bin_triangles(indices: &[u32], screen: &[[f32; 3]], w: usize, h: usize) -> Vec<Vec<u32>> {
    let mut bands = vec![Vec::new(); h.div_ceil(BAND_ROWS)];
    for (t, tri) in indices.chunks_exact(3).enumerate() {
        let [a, b, c] = [0, 1, 2].map(|k| screen[tri[k] as usize]);
        let (min_x, max_x) = (a[0].min(b[0]).min(c[0]), a[0].max(b[0]).max(c[0]));
        let (min_y, max_y) = (a[1].min(b[1]).min(c[1]), a[1].max(b[1]).max(c[1]));
        // Pixel centres sit at +0.5; rows min_y-0.5 ..= max_y-0.5 can be covered.
        if !(max_x >= 0.5 && min_x <= w as f32 - 0.5 && max_y >= 0.5 && min_y <= h as f32 - 0.5) {
            continue;
        }
        let first_row = (min_y - 0.5).ceil().max(0.0) as usize;
        let last_row = ((max_y - 0.5).floor() as usize).min(h - 1);
        if first_row > last_row {
            continue;
        }
        for band in bands.iter_mut().take(last_row / BAND_ROWS + 1).skip(first_row / BAND_ROWS) {
            band.push(t as u32);
        }
    }
    bands
}

/// The nearest triangle at a pixel and the barycentric weights of its second and third
/// vertices there.
pub(super) struct Hit {
    pub(super) triangle: u32,
    pub(super) weights: [f32; 2],
    /// Whether the triangle is seen from its back (clockwise on screen).
    pub(super) back_facing: bool,
}

/// Z-buffered visibility for rows `y0..y0 + rows`: pixel centres inside or on a triangle's
/// edges, the nearest depth winning and the earlier triangle winning ties.
pub(super) fn rasterize_band(
    triangles: &[u32],
    indices: &[u32],
    screen: &[[f32; 3]],
    w: usize,
    y0: usize,
    rows: usize,
) -> Vec<Option<Hit>> {
    let mut depth = vec![f32::INFINITY; w * rows];
    let mut hits: Vec<Option<Hit>> = (0..w * rows).map(|_| None).collect();
    for &t in triangles {
        let tri = &indices[t as usize * 3..t as usize * 3 + 3];
        let [a, b, c] = [0, 1, 2].map(|k| screen[tri[k] as usize]);
        let area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
        if area == 0.0 || !area.is_finite() {
            continue;
        }
        let min_x = ((a[0].min(b[0]).min(c[0]) - 0.5).ceil().max(0.0)) as usize;
        let max_x = (a[0].max(b[0]).max(c[0]) - 0.5).floor();
        let min_y = ((a[1].min(b[1]).min(c[1]) - 0.5).ceil().max(y0 as f32)) as usize;
        let max_y = (a[1].max(b[1]).max(c[1]) - 0.5).floor();
        if max_x < 0.0 || max_y < y0 as f32 {
            continue;
        }
        let (max_x, max_y) = ((max_x as usize).min(w - 1), (max_y as usize).min(y0 + rows - 1));
        let inv_area = 1.0 / area;
        for y in min_y..=max_y {
            let py = y as f32 + 0.5;
            for x in min_x..=max_x {
                let px = x as f32 + 0.5;
                // Edge functions over the signed area: the barycentric weights of a, b and c.
                let wa = ((c[0] - b[0]) * (py - b[1]) - (c[1] - b[1]) * (px - b[0])) * inv_area;
                let wb = ((a[0] - c[0]) * (py - c[1]) - (a[1] - c[1]) * (px - c[0])) * inv_area;
                let wc = 1.0 - wa - wb;
                if wa < 0.0 || wb < 0.0 || wc < 0.0 {
                    continue;
                }
                let z = wa * a[2] + wb * b[2] + wc * c[2];
                let i = (y - y0) * w + x;
                if z < depth[i] {
                    depth[i] = z;
                    // Counter-clockwise from the front is clockwise in y-down pixels.
                    hits[i] = Some(Hit { triangle: t, weights: [wb, wc], back_facing: area > 0.0 });
                }
            }
        }
    }
    hits
}

/// Linear colour of a surface pixel: interpolated albedo under ambient, sky and sun light.
fn shade(g: &Geometry, camera: &Camera, hit: &Hit) -> [f32; 3] {
    let tri = &g.indices[hit.triangle as usize * 3..hit.triangle as usize * 3 + 3];
    let [wb, wc] = hit.weights;
    let wa = 1.0 - wb - wc;
    let mix = |v: &[[f32; 3]]| -> [f32; 3] {
        let (a, b, c) = (v[tri[0] as usize], v[tri[1] as usize], v[tri[2] as usize]);
        std::array::from_fn(|k| wa * a[k] + wb * b[k] + wc * c[k])
    };
    let mut n = normalize(mix(&g.normals));
    // Both sides of open surfaces are lit as seen.
    if hit.back_facing {
        n = n.map(|v| -v);
    }
    let albedo = mix(&g.albedo);
    let light = AMBIENT + SKY_FILL * (n[1] * 0.5 + 0.5) + SUN * dot(n, camera.sun).max(0.0);
    albedo.map(|v| v * light)
}

/// The ground plane at the lowest y: its lit colour, fading out beyond the scene's footprint,
/// darkened by a soft shadow of the scene cast along the sun.
struct Ground {
    y_m: f32,
    center: [f32; 2],
    radius_m: f32,
    /// Lower x, z corner of the shadow mask and its cell size.
    mask_origin: [f32; 2],
    cell_m: f32,
    /// Shadow per cell in [0, 1], softened.
    shadow: Vec<f32>,
    lit: [f32; 3],
    shaded: [f32; 3],
}

impl Ground {
    fn new(camera: &Camera, frame: &Frame, g: &Geometry, (lo, hi): ([f32; 3], [f32; 3])) -> Option<Self> {
        // Seen edge-on or from below, the ground would hide nothing useful.
        if camera.back[1] < 0.02 || camera.sun[1] <= 0.05 || frame.px_per_m <= 0.0 {
            return None;
        }
        let center = [(lo[0] + hi[0]) / 2.0, (lo[2] + hi[2]) / 2.0];
        let half_diagonal = ((hi[0] - lo[0]).powi(2) + (hi[2] - lo[2]).powi(2)).sqrt() / 2.0;
        // A flat or thin scene still gets a ground patch in proportion to its height.
        let radius_m = half_diagonal.max((hi[1] - lo[1]) * 0.5).max(1e-3);
        // Shadows reach as far as the sun's slant carries the scene's top.
        let reach = radius_m + (hi[1] - lo[1]) * camera.sun[0].hypot(camera.sun[2]) / camera.sun[1];
        let half = reach.max(radius_m * 2.0);
        let cell_m = 2.0 * half / SHADOW_CELLS as f32;
        let mask_origin = [center[0] - half, center[1] - half];
        let mut cover = vec![0.0f32; SHADOW_CELLS * SHADOW_CELLS];
        let y_m = lo[1];
        let cast = |p: [f32; 3]| {
            let t = (p[1] - y_m) / camera.sun[1];
            [(p[0] - camera.sun[0] * t - mask_origin[0]) / cell_m, (p[2] - camera.sun[2] * t - mask_origin[1]) / cell_m]
        };
        for tri in g.indices.chunks_exact(3) {
            let [a, b, c] = [0, 1, 2].map(|k| cast(g.positions[tri[k] as usize]));
            fill_triangle(&mut cover, SHADOW_CELLS, a, b, c);
        }
        let shadow = box_blur(box_blur(cover, SHADOW_CELLS, SHADOW_BLUR), SHADOW_CELLS, SHADOW_BLUR);
        let albedo = GROUND_SRGB.map(srgb_to_linear);
        let sky = AMBIENT + SKY_FILL;
        let lit = albedo.map(|v| v * (sky + SUN * camera.sun[1]));
        let shaded = albedo.map(|v| v * (sky + SUN * camera.sun[1] * (1.0 - SHADOW_STRENGTH)));
        Some(Self { y_m, center, radius_m, mask_origin, cell_m, shadow, lit, shaded })
    }

    /// Linear colour and opacity of the ground seen through a pixel, if any shows there.
    fn at_pixel(&self, camera: &Camera, frame: &Frame, x: usize, y: usize) -> Option<([f32; 3], f32)> {
        let [u, v] = frame.unproject(x, y);
        // The pixel's ray is u·right + v·up − t·back; find where it meets y = y_m.
        let t = (v * camera.up[1] - self.y_m) / camera.back[1];
        let p: [f32; 3] = std::array::from_fn(|k| u * camera.right[k] + v * camera.up[k] - t * camera.back[k]);
        let distance = (p[0] - self.center[0]).hypot(p[2] - self.center[1]) / self.radius_m;
        // Opaque out to the footprint, gone by twice its radius.
        let weight = 1.0 - smoothstep(1.0, 2.0, distance);
        if weight <= 0.0 {
            return None;
        }
        let shadow =
            self.shadow_at((p[0] - self.mask_origin[0]) / self.cell_m, (p[2] - self.mask_origin[1]) / self.cell_m);
        let color = std::array::from_fn(|k| self.lit[k] + (self.shaded[k] - self.lit[k]) * shadow);
        Some((color, weight))
    }

    /// Bilinear lookup in cell units (cell centres at +0.5), zero outside.
    fn shadow_at(&self, cx: f32, cz: f32) -> f32 {
        let (fx, fz) = (cx - 0.5, cz - 0.5);
        let (x0, z0) = (fx.floor(), fz.floor());
        let (tx, tz) = (fx - x0, fz - z0);
        let n = SHADOW_CELLS as i64;
        let cell = |x: i64, z: i64| {
            if (0..n).contains(&x) && (0..n).contains(&z) {
                self.shadow[(z * n + x) as usize]
            } else {
                0.0
            }
        };
        let (x0, z0) = (x0 as i64, z0 as i64);
        let top = cell(x0, z0) * (1.0 - tx) + cell(x0 + 1, z0) * tx;
        let bottom = cell(x0, z0 + 1) * (1.0 - tx) + cell(x0 + 1, z0 + 1) * tx;
        top * (1.0 - tz) + bottom * tz
    }
}

/// Set to 1 the cells of an `n`×`n` grid whose centres lie in the triangle (cell units).
fn fill_triangle(cover: &mut [f32], n: usize, a: [f32; 2], b: [f32; 2], c: [f32; 2]) {
    let area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    if area == 0.0 || !area.is_finite() {
        return;
    }
    let lo = |v: f32| (v - 0.5).ceil().max(0.0) as usize;
    let hi = |v: f32| ((v - 0.5).floor().max(-1.0) as i64).min(n as i64 - 1);
    let (x0, x1) = (lo(a[0].min(b[0]).min(c[0])), hi(a[0].max(b[0]).max(c[0])));
    let (z0, z1) = (lo(a[1].min(b[1]).min(c[1])), hi(a[1].max(b[1]).max(c[1])));
    let side =
        |p: [f32; 2], q: [f32; 2], x: f32, z: f32| ((q[0] - p[0]) * (z - p[1]) - (q[1] - p[1]) * (x - p[0])) * area;
    for z in z0 as i64..=z1 {
        for x in x0 as i64..=x1 {
            let (px, pz) = (x as f32 + 0.5, z as f32 + 0.5);
            if side(b, c, px, pz) >= 0.0 && side(c, a, px, pz) >= 0.0 && side(a, b, px, pz) >= 0.0 {
                cover[z as usize * n + x as usize] = 1.0;
            }
        }
    }
}

/// Mean over a (2r+1)² box, cells beyond the grid counting as zero; separable.
fn box_blur(grid: Vec<f32>, n: usize, r: usize) -> Vec<f32> {
    let scale = 1.0 / (2 * r + 1) as f32;
    let pass = |src: &[f32], stride_along: usize, stride_across: usize| -> Vec<f32> {
        let mut out = vec![0.0f32; n * n];
        for across in 0..n {
            for along in 0..n {
                let sum: f32 = (along.saturating_sub(r)..=(along + r).min(n - 1))
                    .map(|k| src[across * stride_across + k * stride_along])
                    .sum();
                out[across * stride_across + along * stride_along] = sum * scale;
            }
        }
        out
    };
    let rows = pass(&grid, 1, n);
    pass(&rows, n, 1)
}

fn smoothstep(edge0: f32, edge1: f32, x: f32) -> f32 {
    let t = ((x - edge0) / (edge1 - edge0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// One sRGB colour per row, from [`SKY_TOP`] to [`SKY_BOTTOM`].
fn sky_rows(h: usize) -> Vec<[u8; 3]> {
    (0..h)
        .map(|y| {
            let t = if h > 1 { y as f32 / (h - 1) as f32 } else { 0.5 };
            std::array::from_fn(|k| (SKY_TOP[k] as f32 + (SKY_BOTTOM[k] as f32 - SKY_TOP[k] as f32) * t).round() as u8)
        })
        .collect()
}

pub(super) const LUT_SIZE: usize = 4096;

/// sRGB bytes of linear values `i / (LUT_SIZE - 1)`, finer than a byte's steps in the darks.
pub(super) fn linear_to_srgb_table() -> &'static [u8; LUT_SIZE] {
    static TABLE: OnceLock<[u8; LUT_SIZE]> = OnceLock::new();
    TABLE.get_or_init(|| {
        std::array::from_fn(|i| {
            let l = i as f64 / (LUT_SIZE - 1) as f64;
            let s = if l <= 0.003_130_8 { l * 12.92 } else { 1.055 * l.powf(1.0 / 2.4) - 0.055 };
            (s * 255.0).round().clamp(0.0, 255.0) as u8
        })
    })
}

pub(super) fn encode_png(rgb: &[u8], w: u32, h: u32) -> Vec<u8> {
    let mut png_bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut png_bytes, w, h);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    encoder.add_text_chunk("Software".to_string(), "Landform".to_string()).expect("valid Latin-1 keyword");
    let mut writer = encoder.write_header().expect("PNG header for a non-empty picture");
    writer.write_image_data(rgb).expect("PNG encoding into memory");
    writer.finish().expect("PNG encoding into memory");
    png_bytes
}

pub(super) fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(super) fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

pub(super) fn normalize(v: [f32; 3]) -> [f32; 3] {
    let len = dot(v, v).sqrt();
    if len > 0.0 && len.is_finite() {
        v.map(|c| c / len)
    } else {
        [0.0, 1.0, 0.0]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::export::test_png::decode;
    use crate::mesh::{extract_isosurface, Mesh, ScalarField, SceneNode};

    fn sphere(radius_m: f32) -> Mesh {
        let n = 40;
        let spacing = radius_m * 2.4 / (n - 1) as f32;
        let origin = [-1.2 * radius_m; 3];
        let values: Vec<f32> = (0..n * n * n)
            .map(|i| {
                let p = [i % n, i / (n * n), (i / n) % n].map(|c| c as f32 * spacing);
                let d = (0..3).map(|k| (p[k] + origin[k]).powi(2)).sum::<f32>().sqrt();
                radius_m - d
            })
            .collect();
        extract_isosurface(
            &ScalarField { dims: [n; 3], origin_m: origin, spacing_m: spacing, values: &values },
            0.0,
            Stop::NEVER,
        )
        .unwrap()
    }

    fn view(width_px: u32, height_px: u32, azimuth_deg: f32, elevation_deg: f32) -> View {
        View { width_px, height_px, azimuth_deg, elevation_deg }
    }

    /// Pixels that differ from their row's background (the row's first pixel).
    /// Pixels that differ from their row's first (the sky), outside the extent label's corner.
    fn foreground(rgb: &[u8], w: usize) -> Vec<(usize, usize, u32)> {
        let mut out = Vec::new();
        let h = rgb.len() / (w * 3);
        for (y, row) in rgb.chunks_exact(w * 3).enumerate() {
            for (x, px) in row.chunks_exact(3).enumerate() {
                if px != &row[..3] && !(x < 160 && y + 24 >= h) {
                    out.push((x, y, px.iter().map(|&v| v as u32).sum()));
                }
            }
        }
        out
    }

    #[test]
    fn picture_has_the_requested_size_as_rgb8() {
        let (info, rgb) =
            decode(&render_png(&Scene::single("ball", sphere(3.0)), &view(320, 200, 30.0, 25.0), Stop::NEVER).unwrap());
        assert_eq!((info.width, info.height), (320, 200));
        assert_eq!((info.color_type, info.bit_depth), (png::ColorType::Rgb, png::BitDepth::Eight));
        assert_eq!(rgb.len(), 320 * 200 * 3);
        // The corner label ("6 x 6 x 6 m", white on a dark outline) sits in the bottom left.
        let white = |x0: usize, y0: usize| {
            (y0..y0 + 24)
                .flat_map(move |y| (x0..x0 + 100).map(move |x| (x, y)))
                .filter(|&(x, y)| rgb[(y * 320 + x) * 3..][..3] == [255, 255, 255])
        };
        assert!(white(0, 176).count() > 40, "the extent label");
        assert_eq!(white(220, 176).count(), 0, "nothing of it on the right");
    }

    #[test]
    fn sphere_is_a_disc_of_its_framed_area_lit_from_the_left() {
        // Level with the ground's plane, which then shows no area.
        let (w, h) = (400, 300);
        let (_, rgb) =
            decode(&render_png(&Scene::single("ball", sphere(5.0)), &view(w, h, 0.0, 0.0), Stop::NEVER).unwrap());
        let disc = foreground(&rgb, w as usize);
        // The bounds are framed to (1 - 2 margin) of the shorter side.
        let radius_px = h as f64 * (1.0 - 2.0 * MARGIN as f64) / 2.0;
        let expected = std::f64::consts::PI * radius_px * radius_px;
        assert!((disc.len() as f64 / expected - 1.0).abs() < 0.1, "{} pixels vs {expected}", disc.len());
        let (cx, cy) = (w as f64 / 2.0, h as f64 / 2.0);
        for &(x, y, _) in &disc {
            let r = ((x as f64 + 0.5 - cx).powi(2) + (y as f64 + 0.5 - cy).powi(2)).sqrt();
            assert!(r < radius_px + 2.0, "pixel ({x}, {y}) outside the disc");
        }
        let mean = |left: bool| {
            let side: Vec<u32> = disc.iter().filter(|&&(x, _, _)| ((x as f64) < cx) == left).map(|p| p.2).collect();
            side.iter().sum::<u32>() as f64 / side.len() as f64
        };
        let (lit, unlit) = (mean(true), mean(false));
        assert!(lit > unlit + 60.0, "left {lit} vs right {unlit}");
    }

    #[test]
    fn empty_scene_is_the_sky_gradient() {
        for scene in [Scene::default(), Scene::single("nothing", Mesh::default())] {
            let (_, rgb) = decode(&render_png(&scene, &view(64, 48, 10.0, 30.0), Stop::NEVER).unwrap());
            let rows: Vec<&[u8]> = rgb.chunks_exact(64 * 3).collect();
            for row in &rows {
                assert!(row.chunks_exact(3).all(|px| px == &row[..3]));
            }
            assert_eq!(&rows[0][..3], &SKY_TOP);
            assert_eq!(&rows[47][..3], &SKY_BOTTOM);
        }
    }

    #[test]
    fn vertex_colours_and_materials_tint_the_surface() {
        let mut red = sphere(2.0);
        red.colors = Some(vec![[220, 30, 30, 255]; red.vertex_count()]);
        let blue = sphere(2.0);
        for (scene, channel) in [
            (Scene::single("red", red), 0),
            (Scene { nodes: vec![SceneNode::new("sea", blue, MaterialKind::Water)] }, 2),
        ] {
            let (_, rgb) = decode(&render_png(&scene, &view(100, 100, 0.0, 0.0), Stop::NEVER).unwrap());
            let center = &rgb[(50 * 100 + 45) * 3..][..3];
            assert!((0..3).all(|k| k == channel || center[channel] > center[k] + 30), "centre {center:?}");
        }
    }

    #[test]
    fn ground_shows_the_shadow_below_right_when_looking_down() {
        // A ball floating above a pebble that sets the ground's height: the sun at the upper
        // left casts the ball's shadow down and to the right of it.
        let mut ball = sphere(2.0);
        for p in &mut ball.positions {
            p[1] += 4.0;
        }
        let pebble = sphere(0.01);
        let scene = Scene {
            nodes: vec![
                SceneNode::new("ball", ball, MaterialKind::default()),
                SceneNode::new("pebble", pebble, MaterialKind::default()),
            ],
        };
        let (w, h) = (200usize, 200usize);
        let v = view(w as u32, h as u32, 0.0, 60.0);
        let (_, rgb) = decode(&render_png(&scene, &v, Stop::NEVER).unwrap());
        let camera = Camera::new(&v);
        let geometry = Geometry::gather(&scene);
        let bounds = geometry.bounds().unwrap();
        let frame = Frame::new(&camera, bounds, w, h);
        let ground = Ground::new(&camera, &frame, &geometry, bounds).expect("ground when looking down");
        // Where the sun ray through the ball's centre meets the ground, and that point mirrored
        // left-right across the ball.
        let t = (4.0 - ground.y_m) / camera.sun[1];
        let shadow = [-camera.sun[0] * t, ground.y_m, -camera.sun[2] * t];
        let mirror = [-shadow[0], shadow[1], shadow[2]];
        let mask = |p: [f32; 3]| {
            ground.shadow_at(
                (p[0] - ground.mask_origin[0]) / ground.cell_m,
                (p[2] - ground.mask_origin[1]) / ground.cell_m,
            )
        };
        assert!(mask(shadow) > 0.95 && mask(mirror) < 0.05, "mask {} vs {}", mask(shadow), mask(mirror));
        let (ball_px, shadow_px) = (frame.project(&camera, [0.0, 4.0, 0.0]), frame.project(&camera, shadow));
        assert!(shadow_px[0] > ball_px[0] && shadow_px[1] > ball_px[1], "shadow at {shadow_px:?}, ball at {ball_px:?}");
        let luma = |p: [f32; 3]| {
            let [x, y, _] = frame.project(&camera, p);
            rgb[(y as usize * w + x as usize) * 3..][..3].iter().map(|&v| v as i32).sum::<i32>()
        };
        let (shaded, sunny) = (luma(shadow), luma(mirror));
        assert!(sunny > shaded + 60, "ground {sunny} in the sun vs {shaded} in the shadow");
    }

    #[test]
    fn same_bytes_on_one_thread_or_two() {
        let mut ball = sphere(3.0);
        ball.colors = Some((0..ball.vertex_count()).map(|i| [(i % 251) as u8, 120, 80, 255]).collect());
        let scene = Scene::single("ball", ball);
        let v = view(300, 220, 35.0, 30.0);
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let two = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        assert_eq!(
            one.install(|| render_png(&scene, &v, Stop::NEVER).unwrap()),
            two.install(|| render_png(&scene, &v, Stop::NEVER).unwrap())
        );
    }
}
