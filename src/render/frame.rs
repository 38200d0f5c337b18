//! A linear RGB image in memory: what `render` and `reference` produce and
//! `compare` reads.
//!
//! Invariant: `pixels.len() == width * height`, row 0 at the top, each pixel
//! the mean outgoing radiance L over its footprint (W / (m² sr)).

/// Luminance of linear Rec.709 / sRGB primaries: 0.2126 R + 0.7152 G +
/// 0.0722 B.
pub fn luminance(rgb: [f32; 3]) -> f32 {
    0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]
}

/// A float RGB image, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear RGB per pixel, row by row from the top.
    pub pixels: Vec<[f32; 3]>,
}

impl Frame {
    /// A black image.
    pub fn new(width: u32, height: u32) -> Frame {
        Frame {
            width,
            height,
            pixels: vec![[0.0; 3]; width as usize * height as usize],
        }
    }

    /// The pixel at column `x`, row `y`.
    pub fn get(&self, x: u32, y: u32) -> [f32; 3] {
        self.pixels[y as usize * self.width as usize + x as usize]
    }
}
