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
}
