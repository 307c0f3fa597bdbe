//! A picture from inside a scene, as a person standing in a cave with a lamp sees it:
//! perspective projection from an eye inside, triangles clipped at a near plane in front of
//! the eye, and light from a lamp in the scene (falling off with distance) plus a little
//! ambient; nothing lit means dark. Visibility and colour share [`super::render`]'s
//! rasteriser and sRGB output; depth is interpolated as 1/z (linear on screen) and colours
//! with perspective-correct weights. Same bytes on any thread count.

use rayon::prelude::*;

use super::render::{
    bin_triangles, cross, dot, encode_png, linear_to_srgb_table, normalize, rasterize_band, Geometry, Hit, BAND_ROWS,
    LUT_SIZE,
};
use super::scale_bar::draw_corner_label;
use crate::mesh::Scene;
use crate::stop::{Stop, Stopped};

/// Where the eye stands and what it looks at, and the lamp.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InsideView {
    pub width_px: u32,
    pub height_px: u32,
    pub eye: [f32; 3],
    pub target: [f32; 3],
    /// Vertical field of view, degrees.
    pub fov_deg: f32,
    pub lamp: [f32; 3],
    /// Distance at which the lamp's light has fallen to half.
    pub lamp_reach_m: f32,
}

/// Light reaching every surface however far from the lamp, and the lamp's strength.
const AMBIENT: f32 = 0.06;
const LAMP: f32 = 1.1;
/// Nearest distance in front of the eye that is drawn, as a share of the lamp's reach.
const NEAR_SHARE: f32 = 0.01;

/// The scene from `view`'s eye, with `label` (e.g. the chamber's size) in the lower-left corner.
pub fn render_inside_png(scene: &Scene, view: &InsideView, label: &str, stop: Stop) -> Result<Vec<u8>, Stopped> {
    let (w, h) = (view.width_px.max(1) as usize, view.height_px.max(1) as usize);
    let forward = normalize(std::array::from_fn(|k| view.target[k] - view.eye[k]));
    let right = normalize(cross(forward, [0.0, 1.0, 0.0]));
    let up = cross(right, forward);
    let focal = 0.5 * h as f32 / (0.5 * view.fov_deg.to_radians()).tan();
    let near = (NEAR_SHARE * view.lamp_reach_m).max(1e-3);
    let clipped = clip_near(Geometry::gather(scene), view.eye, forward, near);
    stop.check()?;
    // Pixel x, y and −1/z: nearer is smaller, and 1/z is linear across the screen.
    let depth_of = |p: [f32; 3]| dot(std::array::from_fn(|k| p[k] - view.eye[k]), forward);
    let screen: Vec<[f32; 3]> = clipped
        .positions
        .par_iter()
        .map(|&p| {
            let d: [f32; 3] = std::array::from_fn(|k| p[k] - view.eye[k]);
            let z = dot(d, forward);
            [0.5 * w as f32 + focal * dot(d, right) / z, 0.5 * h as f32 - focal * dot(d, up) / z, -1.0 / z]
        })
        .collect();
    let depths: Vec<f32> = clipped.positions.iter().map(|&p| depth_of(p)).collect();
    let bands = bin_triangles(&clipped.indices, &screen, w, h);
    stop.check()?;
    let to_srgb = linear_to_srgb_table();
    let mut rgb = vec![0u8; w * h * 3];
    rgb.par_chunks_mut(w * 3 * BAND_ROWS).zip(&bands).enumerate().for_each(|(band, (out, triangles))| {
        if stop.requested() {
            return;
        }
        let y0 = band * BAND_ROWS;
        let rows = out.len() / (w * 3);
        let hits = rasterize_band(triangles, &clipped.indices, &screen, w, y0, rows);
        for (i, hit) in hits.iter().enumerate() {
            let Some(hit) = hit else { continue };
            let linear = shade(&clipped, &depths, hit, view);
            for k in 0..3 {
                out[i * 3 + k] = to_srgb[(linear[k].clamp(0.0, 1.0) * (LUT_SIZE - 1) as f32).round() as usize];
            }
        }
    });
    stop.check()?;
    draw_corner_label(&mut rgb, w, h, label);
    Ok(encode_png(&rgb, w as u32, h as u32))
}

/// Linear colour of a pixel: albedo under the lamp (Lambert, falling off with distance) and
/// ambient, both sides of a surface lit as seen.
fn shade(g: &Geometry, depths: &[f32], hit: &Hit, view: &InsideView) -> [f32; 3] {
    let tri = &g.indices[hit.triangle as usize * 3..hit.triangle as usize * 3 + 3];
    let [wb, wc] = hit.weights;
    // Screen weights to the surface's own (perspective-correct) weights.
    let screen = [1.0 - wb - wc, wb, wc];
    let raw: [f32; 3] = std::array::from_fn(|k| screen[k] / depths[tri[k] as usize]);
    let sum: f32 = raw.iter().sum();
    let weights = raw.map(|v| v / sum);
    let mix = |v: &[[f32; 3]]| -> [f32; 3] {
        std::array::from_fn(|k| (0..3).map(|j| weights[j] * v[tri[j] as usize][k]).sum())
    };
    let p = mix(&g.positions);
    let mut n = normalize(mix(&g.normals));
    if hit.back_facing {
        n = n.map(|v| -v);
    }
    let to_lamp: [f32; 3] = std::array::from_fn(|k| view.lamp[k] - p[k]);
    let distance = dot(to_lamp, to_lamp).sqrt().max(1e-6);
    let lambert = (dot(n, to_lamp) / distance).max(0.0);
    let falloff = 1.0 / (1.0 + (distance / view.lamp_reach_m).powi(2));
    let light = AMBIENT + LAMP * lambert * falloff;
    mix(&g.albedo).map(|v| v * light)
}

/// The triangles of `g` cut at the plane `near` in front of `eye` along `forward`: what lies
/// behind it is dropped, a triangle crossing it becomes one or two whose new corners (position,
/// normal and albedo interpolated along the cut edges) are appended; the others keep their
/// vertices, so the geometry is not copied.
fn clip_near(mut g: Geometry, eye: [f32; 3], forward: [f32; 3], near: f32) -> Geometry {
    let ahead: Vec<f32> =
        g.positions.iter().map(|p| dot(std::array::from_fn(|k| p[k] - eye[k]), forward) - near).collect();
    let old_indices = std::mem::take(&mut g.indices);
    let mut indices = Vec::with_capacity(old_indices.len());
    for tri in old_indices.chunks_exact(3) {
        let corners = [tri[0] as usize, tri[1] as usize, tri[2] as usize];
        let d = corners.map(|i| ahead[i]);
        if d.iter().all(|&v| v >= 0.0) {
            indices.extend_from_slice(tri);
            continue;
        }
        if d.iter().all(|&v| v < 0.0) {
            continue;
        }
        // Sutherland–Hodgman against one plane.
        let mut polygon: Vec<u32> = Vec::with_capacity(4);
        for k in 0..3 {
            let (a, b) = (k, (k + 1) % 3);
            if d[a] >= 0.0 {
                polygon.push(corners[a] as u32);
            }
            if (d[a] >= 0.0) != (d[b] >= 0.0) {
                let t = d[a] / (d[a] - d[b]);
                let (ia, ib) = (corners[a], corners[b]);
                let lerp =
                    |v: &[[f32; 3]]| -> [f32; 3] { std::array::from_fn(|j| v[ia][j] + t * (v[ib][j] - v[ia][j])) };
                let (p, n, c) = (lerp(&g.positions), lerp(&g.normals), lerp(&g.albedo));
                polygon.push(g.positions.len() as u32);
                g.positions.push(p);
                g.normals.push(n);
                g.albedo.push(c);
            }
        }
        for k in 1..polygon.len().saturating_sub(1) {
            indices.extend([polygon[0], polygon[k], polygon[k + 1]]);
        }
    }
    g.indices = indices;
    g
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::export::test_png::decode;
    use crate::mesh::{MaterialKind, Mesh, SceneNode};

    /// A wall facing −Z at z = 0, x and y from −5 to 5 m, light grey.
    fn wall() -> Scene {
        let mesh = Mesh {
            positions: vec![[-5.0, -5.0, 0.0], [5.0, -5.0, 0.0], [5.0, 5.0, 0.0], [-5.0, 5.0, 0.0]],
            normals: vec![[0.0, 0.0, -1.0]; 4],
            uvs: vec![[0.0; 2]; 4],
            colors: None,
            indices: vec![0, 2, 1, 0, 3, 2],
        };
        Scene { nodes: vec![SceneNode::new("wall", mesh, MaterialKind::VertexColors)] }
    }

    fn view(eye_z: f32, lamp: [f32; 3]) -> InsideView {
        InsideView {
            width_px: 64,
            height_px: 48,
            eye: [0.0, 0.0, eye_z],
            target: [0.0, 0.0, 0.0],
            fov_deg: 60.0,
            lamp,
            lamp_reach_m: 2.0,
        }
    }

    fn brightness(png: &[u8], x: usize, y: usize) -> u32 {
        let (info, px) = decode(png);
        let i = (y * info.width as usize + x) * 3;
        px[i..i + 3].iter().map(|&v| u32::from(v)).sum()
    }

    #[test]
    fn the_lamp_lights_what_faces_it_and_falls_off_with_distance() {
        let near = render_inside_png(&wall(), &view(-2.0, [0.0, 0.0, -2.0]), "", Stop::NEVER).unwrap();
        let far = render_inside_png(&wall(), &view(-12.0, [0.0, 0.0, -12.0]), "", Stop::NEVER).unwrap();
        // Six times the reach away the wall is darker (falloff 1/37 against 1/2).
        let (lit, dim) = (brightness(&near, 32, 24), brightness(&far, 32, 24));
        assert!(lit > dim + 60, "{lit} vs {dim}");
        // From 12 m with a 60° field of view the picture spans ±6.9 m up and ±9.2 m across:
        // the 10 m wall fills rows 7 to 41 of 48 in the middle, and the corners are dark.
        assert_eq!(brightness(&far, 0, 0), 0);
        assert_eq!(brightness(&far, 32, 2), 0, "above the wall");
        assert!(brightness(&far, 32, 10) > 0, "the wall's upper part");
    }

    #[test]
    fn what_lies_behind_the_eye_is_cut_away() {
        // The eye stands beyond the wall (z = 1, looking at z = 2): the wall is behind it.
        let v = InsideView { eye: [0.0, 0.0, 1.0], target: [0.0, 0.0, 2.0], ..view(0.0, [0.0, 0.0, 1.0]) };
        let png = render_inside_png(&wall(), &v, "", Stop::NEVER).unwrap();
        let (_, px) = decode(&png);
        assert!(px.iter().all(|&b| b == 0), "nothing in front of the eye");
        // A floor running from behind the eye to far ahead is cut at the near plane, not
        // dropped: it fills the lower half of the picture, and nothing is drawn above the
        // horizon.
        let floor = Mesh {
            positions: vec![[-20.0, -1.0, -10.0], [20.0, -1.0, -10.0], [20.0, -1.0, 30.0], [-20.0, -1.0, 30.0]],
            normals: vec![[0.0, 1.0, 0.0]; 4],
            uvs: vec![[0.0; 2]; 4],
            colors: None,
            indices: vec![0, 2, 1, 0, 3, 2],
        };
        let scene = Scene { nodes: vec![SceneNode::new("floor", floor, MaterialKind::VertexColors)] };
        let v = InsideView { eye: [0.0, 0.0, 0.0], target: [0.0, 0.0, 5.0], ..view(0.0, [0.0, 0.5, 0.0]) };
        let png = render_inside_png(&scene, &v, "", Stop::NEVER).unwrap();
        assert!(brightness(&png, 32, 47) > 0, "the floor just in front of the eye");
        assert!(brightness(&png, 32, 30) > 0, "the floor ahead");
        assert_eq!(brightness(&png, 32, 10), 0, "nothing above the horizon");
    }
}
