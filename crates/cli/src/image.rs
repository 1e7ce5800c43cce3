//! 8-bit grayscale PNG previews.

use anyhow::Context;

/// A grayscale image, row-major, row 0 at the top.
#[derive(Debug, Clone, PartialEq)]
pub struct Gray {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width * height` values.
    pub pixels: Vec<u8>,
}

impl Gray {
    /// An image of `values` (row-major, `width * height`) mapped by `gray = min(255, round(255 v / white))`;
    /// non-finite or negative values are black. `white <= 0` gives a black image.
    pub fn from_values(width: usize, height: usize, values: &[f64], white: f64) -> Self {
        debug_assert_eq!(values.len(), width * height);
        let pixels = values
            .iter()
            .map(|&v| {
                if white > 0.0 && v.is_finite() && v > 0.0 {
                    (255.0 * v / white).round().min(255.0) as u8
                } else {
                    0
                }
            })
            .collect();
        Self {
            width,
            height,
            pixels,
        }
    }

    /// The image enlarged `scale` times by pixel replication.
    pub fn upscaled(&self, scale: usize) -> Self {
        let scale = scale.max(1);
        let (w, h) = (self.width * scale, self.height * scale);
        let mut pixels = Vec::with_capacity(w * h);
        for row in self.pixels.chunks_exact(self.width.max(1)) {
            let wide: Vec<u8> = row
                .iter()
                .flat_map(|&p| std::iter::repeat_n(p, scale))
                .collect();
            for _ in 0..scale {
                pixels.extend_from_slice(&wide);
            }
        }
        Self {
            width: w,
            height: h,
            pixels,
        }
    }

    /// A `width x height` image of one gray level.
    pub fn filled(width: usize, height: usize, gray: u8) -> Self {
        Self {
            width,
            height,
            pixels: vec![gray; width * height],
        }
    }

    /// Copies `other` into this image with its top-left corner at `(x, y)`, clipped.
    pub fn blit(&mut self, other: &Gray, x: usize, y: usize) {
        for r in 0..other.height.min(self.height.saturating_sub(y)) {
            let w = other.width.min(self.width.saturating_sub(x));
            let to = (y + r) * self.width + x;
            self.pixels[to..to + w]
                .copy_from_slice(&other.pixels[r * other.width..r * other.width + w]);
        }
    }

    /// Writes `text` in gray level `gray` with its top-left corner at `(x, y)`, clipped: a
    /// 5 x 7 pixel font, each font pixel `scale x scale`, [`GLYPH_ADVANCE`] font pixels per
    /// character. It knows the digits, `. = + - ± Δ g` and the space; other characters are
    /// left blank.
    pub fn text(&mut self, x: usize, y: usize, text: &str, scale: usize, gray: u8) {
        for (i, ch) in text.chars().enumerate() {
            let rows = glyph(ch);
            let left = x + i * GLYPH_ADVANCE * scale;
            for (r, bits) in rows.iter().enumerate() {
                for c in 0..5 {
                    if bits & (0b10000 >> c) == 0 {
                        continue;
                    }
                    for dy in 0..scale {
                        for dx in 0..scale {
                            let (px, py) = (left + c * scale + dx, y + r * scale + dy);
                            if px < self.width && py < self.height {
                                self.pixels[py * self.width + px] = gray;
                            }
                        }
                    }
                }
            }
        }
    }

    /// PNG file contents.
    pub fn encode_png(&self) -> anyhow::Result<Vec<u8>> {
        let mut out = Vec::new();
        let mut encoder = png::Encoder::new(&mut out, self.width as u32, self.height as u32);
        encoder.set_color(png::ColorType::Grayscale);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header().context("encoding a PNG header")?;
        writer
            .write_image_data(&self.pixels)
            .context("encoding PNG data")?;
        writer.finish().context("finishing a PNG")?;
        Ok(out)
    }
}

/// Font pixels from one character of [`Gray::text`] to the next (5 wide, 1 apart).
pub const GLYPH_ADVANCE: usize = 6;

/// Font pixels of a glyph's height.
pub const GLYPH_HEIGHT: usize = 7;

/// The width of `text` in [`Gray::text`] at `scale`, pixels (without the last gap).
pub fn text_width(text: &str, scale: usize) -> usize {
    (text.chars().count() * GLYPH_ADVANCE).saturating_sub(1) * scale
}

/// The 5 x 7 glyph of `ch`, one row of five bits (the leftmost the highest) per font row.
fn glyph(ch: char) -> [u8; 7] {
    match ch {
        '0' => [0x0e, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0e],
        '1' => [0x04, 0x0c, 0x04, 0x04, 0x04, 0x04, 0x0e],
        '2' => [0x0e, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1f],
        '3' => [0x1f, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0e],
        '4' => [0x02, 0x06, 0x0a, 0x12, 0x1f, 0x02, 0x02],
        '5' => [0x1f, 0x10, 0x1e, 0x01, 0x01, 0x11, 0x0e],
        '6' => [0x06, 0x08, 0x10, 0x1e, 0x11, 0x11, 0x0e],
        '7' => [0x1f, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08],
        '8' => [0x0e, 0x11, 0x11, 0x0e, 0x11, 0x11, 0x0e],
        '9' => [0x0e, 0x11, 0x11, 0x0f, 0x01, 0x02, 0x0c],
        '.' => [0x00, 0x00, 0x00, 0x00, 0x00, 0x0c, 0x0c],
        '=' => [0x00, 0x00, 0x1f, 0x00, 0x1f, 0x00, 0x00],
        '-' => [0x00, 0x00, 0x00, 0x1f, 0x00, 0x00, 0x00],
        '+' => [0x00, 0x04, 0x04, 0x1f, 0x04, 0x04, 0x00],
        '±' => [0x04, 0x04, 0x1f, 0x04, 0x04, 0x00, 0x1f],
        'Δ' => [0x04, 0x04, 0x0a, 0x0a, 0x11, 0x11, 0x1f],
        'g' => [0x00, 0x0f, 0x11, 0x11, 0x0f, 0x01, 0x0e],
        _ => [0; 7],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mapping_scaling_and_encoding() {
        let g = Gray::from_values(2, 1, &[0.5, 4.0], 1.0);
        assert_eq!(g.pixels, vec![128, 255]);
        let big = g.upscaled(3);
        assert_eq!((big.width, big.height), (6, 3));
        assert_eq!(&big.pixels[..6], &[128, 128, 128, 255, 255, 255]);
        let png = big.encode_png().unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    }

    #[test]
    fn text_and_blit() {
        let mut g = Gray::filled(20, 10, 255);
        g.text(1, 1, "1", 1, 0);
        // The 1's foot: five pixels wide... its middle three, at font row 6.
        assert_eq!(&g.pixels[7 * 20 + 2..7 * 20 + 5], &[0, 0, 0]);
        assert_eq!(g.pixels[0], 255);
        assert_eq!(text_width("12", 2), 22);
        // Clipped at the edges, no panic.
        g.text(18, 8, "8Δ", 3, 0);
        let mut big = Gray::filled(4, 4, 0);
        big.blit(&Gray::filled(3, 3, 9), 2, 2);
        assert_eq!(big.pixels, [0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 9, 9, 0, 0, 9, 9]);
    }
}
