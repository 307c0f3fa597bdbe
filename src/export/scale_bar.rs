//! Scale in pictures: for pictures seen from straight above, a scale bar: a white bar with a dark outline in the
//! bottom-left corner, a round length (1, 2 or 5 × a power of ten metres, at most 30 % of the
//! width) and its label ("50 m", "2 km") above it, drawn with a small bitmap font; for
//! perspective renders, whose scale changes across the picture, the extent in metres as a
//! corner label. Pictures under [`MIN_SIDE_PX`] on a side are left alone: the marks would hide
//! too much of them.

/// Smallest side a picture needs for a scale bar.
pub const MIN_SIDE_PX: usize = 96;
/// Longest bar, as a share of the picture's width.
const MAX_SHARE: f64 = 0.3;
/// Glyph cells are 3 × 5 font pixels, each drawn as `scale` × `scale` picture pixels: 2 up
/// to pictures 500 px on their shorter side, 3 to 750, then 4.
fn scale_for(width: usize, height: usize) -> usize {
    (width.min(height) / 250).clamp(2, 4)
}
const MARGIN: usize = 6;
const BAR_HEIGHT: usize = 4;

/// The glyphs the labels need: 5 rows of 3 bits, the high bit on the left ('m' is 5 wide).
fn glyph(c: char) -> Option<(usize, [u8; 5])> {
    if c == 'm' {
        return Some((5, [0b00000, 0b00000, 0b11110, 0b10101, 0b10101]));
    }
    let rows = match c {
        '0' => [0b111, 0b101, 0b101, 0b101, 0b111],
        '1' => [0b010, 0b110, 0b010, 0b010, 0b111],
        '2' => [0b111, 0b001, 0b111, 0b100, 0b111],
        '3' => [0b111, 0b001, 0b011, 0b001, 0b111],
        '4' => [0b101, 0b101, 0b111, 0b001, 0b001],
        '5' => [0b111, 0b100, 0b111, 0b001, 0b111],
        '6' => [0b111, 0b100, 0b111, 0b101, 0b111],
        '7' => [0b111, 0b001, 0b010, 0b010, 0b010],
        '8' => [0b111, 0b101, 0b111, 0b101, 0b111],
        '9' => [0b111, 0b101, 0b111, 0b001, 0b111],
        'k' => [0b100, 0b101, 0b110, 0b101, 0b101],
        ' ' => [0; 5],
        '.' => [0b000, 0b000, 0b000, 0b000, 0b010],
        'x' => [0b000, 0b000, 0b101, 0b010, 0b101],
        _ => return None,
    };
    Some((3, rows))
}

/// The bar's length in metres for a picture `width_px` wide at `metres_per_px`: the longest
/// 1, 2 or 5 × 10ⁿ that fits in 30 % of the width.
pub fn bar_metres(width_px: usize, metres_per_px: f64) -> f64 {
    let most = width_px as f64 * MAX_SHARE * metres_per_px;
    let mut power = 10f64.powf(most.log10().floor());
    loop {
        for m in [5.0, 2.0, 1.0] {
            if m * power <= most {
                return m * power;
            }
        }
        power /= 10.0;
    }
}

fn label(metres: f64) -> String {
    // Rounded so that 2 × 0.1 reads "0.2", not its binary neighbour.
    let round = |v: f64| (v * 1e6).round() / 1e6;
    if metres >= 1000.0 {
        format!("{} km", round(metres / 1000.0))
    } else {
        format!("{} m", round(metres))
    }
}

/// Draw the bar into `rgb` (`width` × `height` pixels, RGB8, rows top to bottom).
pub fn draw_scale_bar(rgb: &mut [u8], width: usize, height: usize, metres_per_px: f64) {
    if width.min(height) < MIN_SIDE_PX || !(metres_per_px > 0.0 && metres_per_px.is_finite()) {
        return;
    }
    let metres = bar_metres(width, metres_per_px);
    let length = (metres / metres_per_px).round() as usize;
    let mut put = |x: usize, y: usize, c: u8| fill_px(rgb, width, height, x, y, c);
    let (x0, y0) = (MARGIN, height - MARGIN - BAR_HEIGHT);
    // The outline first, one pixel round the bar, then the bar.
    for y in y0 - 1..=y0 + BAR_HEIGHT {
        for x in x0 - 1..=x0 + length {
            put(x, y, 20);
        }
    }
    for y in y0..y0 + BAR_HEIGHT {
        for x in x0..x0 + length {
            put(x, y, 255);
        }
    }
    // The label, outlined, above the bar's left end.
    let scale = scale_for(width, height);
    draw_text(rgb, width, height, (x0, y0 - 2 - 5 * scale - 2), scale, &label(metres));
}

/// Write `text` in the bottom-left corner of a picture at least [`MIN_SIDE_PX`] on a side.
pub fn draw_corner_label(rgb: &mut [u8], width: usize, height: usize, text: &str) {
    if width.min(height) >= MIN_SIDE_PX {
        let scale = scale_for(width, height);
        draw_text(rgb, width, height, (MARGIN, height - MARGIN - 5 * scale), scale, text);
    }
}

/// White text with a dark outline, its top-left corner at `(x0, top)`; characters without a
/// glyph are skipped.
fn draw_text(rgb: &mut [u8], width: usize, height: usize, (x0, top): (usize, usize), scale: usize, text: &str) {
    let mut put = |x: usize, y: usize, c: u8| fill_px(rgb, width, height, x, y, c);
    let glyphs: Vec<(usize, [u8; 5])> = text.chars().filter_map(glyph).collect();
    for pass in [20u8, 255] {
        let mut left = 0;
        for &(glyph_width, rows) in &glyphs {
            for (row, bits) in rows.iter().enumerate() {
                for col in 0..glyph_width {
                    if bits & (1 << (glyph_width - 1 - col)) == 0 {
                        continue;
                    }
                    let (px, py) = (x0 + (left + col) * scale, top + row * scale);
                    for dy in 0..scale {
                        for dx in 0..scale {
                            if pass == 20 {
                                for (ox, oy) in [(0, 1), (2, 1), (1, 0), (1, 2)] {
                                    put(px + dx + ox - 1, py + dy + oy - 1, 20);
                                }
                            } else {
                                put(px + dx, py + dy, 255);
                            }
                        }
                    }
                }
            }
            left += glyph_width + 1;
        }
    }
}

/// Paint pixel (`x`, `y`) grey level `c`, if it lies in the picture.
fn fill_px(rgb: &mut [u8], width: usize, height: usize, x: usize, y: usize, c: u8) {
    if x < width && y < height {
        rgb[(y * width + x) * 3..][..3].fill(c);
    }
}

/// A length for a label: whole metres from 10 m, one decimal below.
pub fn metres_text(m: f32) -> String {
    if m >= 10.0 {
        format!("{}", m.round())
    } else {
        format!("{}", (m * 10.0).round() / 10.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bar_is_the_longest_round_length_within_30_percent() {
        // 257 px at 1 m: at most 77.1 m → 50 m. At 4 m/px: 308.4 → 200. 256 px at 0.05 m:
        // 3.84 → 2 m. 300 px at 50 m: 4500 → 2 km.
        assert_eq!(bar_metres(257, 1.0), 50.0);
        assert_eq!(bar_metres(257, 4.0), 200.0);
        assert_eq!(bar_metres(256, 0.05), 2.0);
        assert_eq!(bar_metres(300, 50.0), 2000.0);
        assert_eq!(label(2000.0), "2 km");
        assert_eq!(label(50.0), "50 m");
        assert_eq!(label(bar_metres(200, 0.005)), "0.2 m");
        assert!(label(0.2).chars().all(|c| glyph(c).is_some()));
        assert_eq!(format!("{} x {} m", metres_text(63.4), metres_text(7.26)), "63 x 7.3 m");
        assert!("63 x 7.3 m".chars().all(|c| glyph(c).is_some()));
    }

    #[test]
    fn the_bar_is_drawn_to_length_in_the_bottom_left_and_small_pictures_are_left_alone() {
        let (w, h) = (257, 200);
        let mut rgb = vec![100u8; w * h * 3];
        draw_scale_bar(&mut rgb, w, h, 1.0);
        // A row through the bar: 50 white pixels from the margin, outlined.
        let y = h - MARGIN - BAR_HEIGHT + 1;
        let row: Vec<u8> = (0..w).map(|x| rgb[(y * w + x) * 3]).collect();
        assert_eq!(row.iter().filter(|&&v| v == 255).count(), 50);
        assert_eq!((row[MARGIN - 1], row[MARGIN], row[MARGIN + 49], row[MARGIN + 50]), (20, 255, 255, 20));
        // The label's white pixels lie above the bar; the top right is untouched.
        let label_rows = (h - 40..h - MARGIN - BAR_HEIGHT - 1).flat_map(|y| (0..60).map(move |x| (x, y)));
        assert!(label_rows.filter(|&(x, y)| rgb[(y * w + x) * 3] == 255).count() > 20);
        assert!(rgb[..w * 3 * 100].iter().all(|&v| v == 100));

        let mut small = vec![100u8; 64 * 64 * 3];
        draw_scale_bar(&mut small, 64, 64, 1.0);
        assert!(small.iter().all(|&v| v == 100));
    }
}
