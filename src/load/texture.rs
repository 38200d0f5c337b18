//! Colour textures: decoding to linear RGB and averaging over a triangle.
//!
//! Owns: turning an encoded PNG/JPEG (sRGB-encoded, as glTF's base colour and
//! emissive textures are) into a grid of linear RGB texels, sampling it
//! through a glTF sampler (wrap modes, nearest or bilinear), and the mean of
//! a texture over a triangle given its texture coordinates.
//!
//! Memory: only the means over triangles are used, so an image of more than
//! [`MAX_KEPT_TEXELS`] texels is kept box-filtered by the smallest whole
//! factor that brings it within that count (12 MiB of f32 RGB). Decoding
//! holds the image in its own pixel format (the header's width × height ×
//! bytes per pixel) plus that kept grid, converted a strip of rows at a
//! time; [`Texture::decode`] checks this against the memory budget from the
//! header, before anything is decoded. An image file is checked the same
//! way, and its size too, before it is read whole ([`check_file`]).
//!
//! Invariants:
//! - Texels are linear (sRGB decoded) before any averaging; alpha is dropped.
//! - An image within [`MAX_KEPT_TEXELS`] is kept texel for texel; a larger
//!   one as the means of f × f blocks (the last row and column of blocks
//!   averaging the texels they hold), so a triangle's mean is that of the
//!   image up to detail finer than a block.
//! - The mean over a triangle uses a stratified, deterministic set of sample
//!   points: the triangle is cut into m² congruent sub-triangles, each
//!   sampled once at a jittered point drawn from a generator with a fixed
//!   seed. m grows with the triangle's footprint in texels, within
//!   `MIN_SPLITS..=MAX_SPLITS`, so the same input gives the same mean.
//! - Texture space follows glTF: (0, 0) is the top-left corner of the image,
//!   u runs right and v runs down.
//!
//! ```text
//!   barycentric split, m = 3 (9 sub-triangles, each with a jittered sample)
//!   p2
//!   |\
//!   |_\
//!   |\ |\
//!   |_\|_\
//!   |\ |\ |\
//!   |_\|_\|_\
//!   p0       p1
//! ```

use std::fs::File;
use std::io::{BufRead, BufReader, Cursor, Seek};
use std::path::Path;

use glam::{DVec2, DVec3};
use gltf::texture::{MagFilter, WrappingMode};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg32;

use crate::classic::uniform::human_bytes;

/// Fewest splits per triangle edge: at least `MIN_SPLITS²` samples.
const MIN_SPLITS: usize = 4;
/// Most splits per triangle edge: at most `MAX_SPLITS²` samples.
const MAX_SPLITS: usize = 64;
/// Samples per texel edge along the triangle's longest texture-space edge.
const SPLITS_PER_TEXEL: f64 = 8.0;
/// Largest decoded image accepted, in texels.
const MAX_TEXELS: u64 = 1 << 26;
/// Largest allocation the image decoder may make, in bytes.
const MAX_DECODE_BYTES: u64 = 1 << 30;
/// Most texels a decoded texture keeps: larger images are box-filtered to
/// within this.
pub(super) const MAX_KEPT_TEXELS: usize = 1 << 20;
/// Fixed seed of the jitter: means are deterministic.
const JITTER_SEED: u64 = 0x6e75_7373_656c_7421;

/// A decoded texture: linear RGB texels, row 0 at the top (v = 0).
#[derive(Debug)]
pub(super) struct Texture {
    width: usize,
    height: usize,
    texels: Vec<[f32; 3]>,
}

/// How a texture is sampled: the glTF sampler's wrap modes and filter.
#[derive(Clone, Copy, Debug)]
pub(super) struct Sampler {
    pub wrap_s: WrappingMode,
    pub wrap_t: WrappingMode,
    pub nearest: bool,
}

impl Sampler {
    pub fn from_gltf(sampler: &gltf::texture::Sampler<'_>) -> Self {
        Sampler {
            wrap_s: sampler.wrap_s(),
            wrap_t: sampler.wrap_t(),
            nearest: sampler.mag_filter() == Some(MagFilter::Nearest),
        }
    }
}

/// The affine map of `KHR_texture_transform`: uv' = offset + R(rotation) ·
/// (scale ⊙ uv), with R rotating u towards v for positive angles as the
/// extension's matrix prescribes.
#[derive(Clone, Copy, Debug)]
pub(super) struct UvTransform {
    pub offset: DVec2,
    pub rotation: f64,
    pub scale: DVec2,
}

impl UvTransform {
    pub fn apply(&self, uv: DVec2) -> DVec2 {
        let s = self.scale * uv;
        let (sin, cos) = self.rotation.sin_cos();
        self.offset + DVec2::new(cos * s.x - sin * s.y, sin * s.x + cos * s.y)
    }
}

/// The sRGB transfer function's inverse (IEC 61966-2-1).
pub(super) fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// An image reader over `input` with its format guessed from the first
/// bytes (PNG or JPEG, else an error) and the decoder's allocations
/// limited to [`MAX_DECODE_BYTES`] and `memory_budget`.
fn image_reader<R: BufRead + Seek>(
    input: R,
    memory_budget: u64,
) -> Result<image::ImageReader<R>, String> {
    let mut reader = image::ImageReader::new(input)
        .with_guessed_format()
        .map_err(|e| e.to_string())?;
    if reader.format().is_none() {
        return Err("not a PNG or JPEG image".to_string());
    }
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(MAX_DECODE_BYTES.min(memory_budget));
    reader.limits(limits);
    Ok(reader)
}

/// Checks the header `reader` reads: the decoded image and the kept
/// texels, with `in_use` bytes already held, must fit `memory_budget`.
fn check_header<R: BufRead + Seek>(
    reader: image::ImageReader<R>,
    memory_budget: u64,
    in_use: u64,
) -> Result<(), String> {
    let decoder = reader.into_decoder().map_err(|e| e.to_string())?;
    let (width, height) = image::ImageDecoder::dimensions(&decoder);
    let decoded = image::ImageDecoder::total_bytes(&decoder);
    drop(decoder);
    if u64::from(width) * u64::from(height) > MAX_TEXELS {
        return Err(format!(
            "{width}×{height} texels exceed the limit of {MAX_TEXELS}"
        ));
    }
    let (kw, kh, _) = reduction(width as usize, height as usize);
    let need = decoded
        .saturating_add(Texture::bytes_of(kw * kh))
        .saturating_add(in_use);
    if need > memory_budget || decoded > MAX_DECODE_BYTES {
        return Err(format!(
            "{width}×{height} texels need {} to decode{}, over the memory budget of {} \
             (raise --memory-budget or use a smaller image)",
            human_bytes(need),
            besides(in_use),
            human_bytes(memory_budget.min(MAX_DECODE_BYTES))
        ));
    }
    Ok(())
}

/// `" besides the N the textures before it keep"`, or nothing for 0.
fn besides(in_use: u64) -> String {
    match in_use {
        0 => String::new(),
        b => format!(
            " besides the {} the textures before it keep",
            human_bytes(b)
        ),
    }
}

/// Checks that a file of `len` bytes, with `in_use` bytes already held,
/// fits `memory_budget`, as it must to be read whole.
pub(super) fn check_file_size(len: u64, memory_budget: u64, in_use: u64) -> Result<(), String> {
    if len.saturating_add(in_use) > memory_budget {
        return Err(format!(
            "the file has {}{}, over the memory budget of {} \
             (raise --memory-budget or use a smaller image)",
            human_bytes(len),
            match in_use {
                0 => String::new(),
                b => format!(" besides the {} already held", human_bytes(b)),
            },
            human_bytes(memory_budget)
        ));
    }
    Ok(())
}

/// Checks the image file at `path` before it is read whole: its header
/// as [`Texture::decode`] does, and its size with [`check_file_size`].
/// A PNG's header is read alone (through a buffered reader, the chunks
/// before the image data), so it is checked first; a JPEG decoder reads
/// its whole input to find the header, so its size is checked first.
pub(super) fn check_file(path: &Path, memory_budget: u64, in_use: u64) -> Result<(), String> {
    let file = File::open(path).map_err(|e| format!("cannot read the file: {e}"))?;
    let len = file
        .metadata()
        .map_err(|e| format!("cannot read the file: {e}"))?
        .len();
    let reader = image_reader(BufReader::new(file), memory_budget)?;
    if reader.format() == Some(image::ImageFormat::Png) {
        check_header(reader, memory_budget, in_use)?;
        check_file_size(len, memory_budget, in_use)
    } else {
        check_file_size(len, memory_budget, in_use)?;
        check_header(reader, memory_budget, in_use)
    }
}

impl Texture {
    /// Decodes a PNG or JPEG and converts it to linear RGB, reduced to at
    /// most [`MAX_KEPT_TEXELS`]. The header's size is checked first: the
    /// decoded image and the kept texels, with `in_use` bytes already
    /// held, must fit `memory_budget`.
    pub fn decode(bytes: &[u8], memory_budget: u64, in_use: u64) -> Result<Texture, String> {
        check_header(
            image_reader(Cursor::new(bytes), memory_budget)?,
            memory_budget,
            in_use,
        )?;
        let image = image_reader(Cursor::new(bytes), memory_budget)?
            .decode()
            .map_err(|e| e.to_string())?;
        Self::reduced(&image)
    }

    /// Bytes `texels` kept texels take.
    fn bytes_of(texels: usize) -> u64 {
        (texels as u64).saturating_mul(std::mem::size_of::<[f32; 3]>() as u64)
    }

    /// Bytes this texture keeps.
    pub fn bytes(&self) -> u64 {
        Self::bytes_of(self.texels.len())
    }

    /// The linear texels of `image`, box-filtered by [`reduction`]'s
    /// factor, converted to f32 a strip of rows (one block high) at a time.
    fn reduced(image: &image::DynamicImage) -> Result<Texture, String> {
        let (w, h) = (image.width() as usize, image.height() as usize);
        if w == 0 || h == 0 {
            return Err("image has no texels".into());
        }
        let (width, height, f) = reduction(w, h);
        let mut texels = Vec::with_capacity(width * height);
        let mut sums = vec![DVec3::ZERO; width];
        for ky in 0..height {
            let y0 = ky * f;
            let rows = f.min(h - y0);
            let strip = image
                .crop_imm(0, y0 as u32, w as u32, rows as u32)
                .to_rgb32f();
            sums.fill(DVec3::ZERO);
            for (x, _, p) in strip.enumerate_pixels() {
                let [r, g, b] = p.0.map(|c| srgb_to_linear(c.clamp(0.0, 1.0)));
                sums[x as usize / f] += DVec3::new(r.into(), g.into(), b.into());
            }
            for (kx, sum) in sums.iter().enumerate() {
                let n = (f.min(w - kx * f) * rows) as f64;
                texels.push((*sum / n).as_vec3().to_array());
            }
        }
        Ok(Texture {
            width,
            height,
            texels,
        })
    }
    /// Builds a texture from linear texels (row-major, row 0 at v = 0).
    #[cfg(test)]
    pub fn from_linear(width: usize, height: usize, texels: Vec<[f32; 3]>) -> Texture {
        assert_eq!(texels.len(), width * height);
        Texture {
            width,
            height,
            texels,
        }
    }

    fn texel(&self, x: usize, y: usize) -> DVec3 {
        let [r, g, b] = self.texels[y * self.width + x];
        DVec3::new(r.into(), g.into(), b.into())
    }

    /// Linear RGB at texture coordinate `uv`.
    pub fn sample(&self, uv: DVec2, sampler: &Sampler) -> DVec3 {
        let (w, h) = (self.width as f64, self.height as f64);
        if sampler.nearest {
            let x = wrap(floor_i64(uv.x * w), self.width, sampler.wrap_s);
            let y = wrap(floor_i64(uv.y * h), self.height, sampler.wrap_t);
            return self.texel(x, y);
        }
        let fx = uv.x * w - 0.5;
        let fy = uv.y * h - 0.5;
        let (x0, y0) = (fx.floor(), fy.floor());
        let (tx, ty) = (fx - x0, fy - y0);
        let (x0, y0) = (floor_i64(x0), floor_i64(y0));
        let xa = wrap(x0, self.width, sampler.wrap_s);
        let xb = wrap(x0.saturating_add(1), self.width, sampler.wrap_s);
        let ya = wrap(y0, self.height, sampler.wrap_t);
        let yb = wrap(y0.saturating_add(1), self.height, sampler.wrap_t);
        let top = self.texel(xa, ya) * (1.0 - tx) + self.texel(xb, ya) * tx;
        let bottom = self.texel(xa, yb) * (1.0 - tx) + self.texel(xb, yb) * tx;
        top * (1.0 - ty) + bottom * ty
    }

    /// Mean of the texture over the triangle whose corners have texture
    /// coordinates `uv` (already transformed), uniform in area.
    pub fn triangle_mean(&self, uv: [DVec2; 3], sampler: &Sampler) -> DVec3 {
        let texels = DVec2::new(self.width as f64, self.height as f64);
        let e1 = (uv[1] - uv[0]) * texels;
        let e2 = (uv[2] - uv[0]) * texels;
        let e3 = (uv[2] - uv[1]) * texels;
        let longest = e1.length().max(e2.length()).max(e3.length());
        let area = 0.5 * e1.perp_dot(e2).abs();
        let want = SPLITS_PER_TEXEL * longest.max((2.0 * area).sqrt());
        let m = if want.is_finite() {
            (want.ceil() as usize).clamp(MIN_SPLITS, MAX_SPLITS)
        } else {
            MAX_SPLITS
        };
        let mut rng = Pcg32::seed_from_u64(JITTER_SEED);
        let mut sum = DVec3::ZERO;
        let step = 1.0 / m as f64;
        let at = |a: f64, b: f64| uv[0] + a * (uv[1] - uv[0]) + b * (uv[2] - uv[0]);
        for i in 0..m {
            for j in 0..m - i {
                let (a, b) = (i as f64 * step, j as f64 * step);
                // Upward sub-triangle (a,b), (a+s,b), (a,b+s).
                let (r1, r2) = unit_triangle_point(rng.random(), rng.random());
                sum += self.sample(at(a + r1 * step, b + r2 * step), sampler);
                if j + 1 < m - i {
                    // Downward sub-triangle (a+s,b+s), (a,b+s), (a+s,b).
                    let (r1, r2) = unit_triangle_point(rng.random(), rng.random());
                    sum += self.sample(at(a + (1.0 - r1) * step, b + (1.0 - r2) * step), sampler);
                }
            }
        }
        sum / (m * m) as f64
    }
}

/// The kept size of a `w` × `h` image and the box factor f that gives it:
/// the smallest f ≥ 1 for which ⌈w/f⌉ · ⌈h/f⌉ ≤ [`MAX_KEPT_TEXELS`].
fn reduction(w: usize, h: usize) -> (usize, usize, usize) {
    let texels = (w as f64) * (h as f64);
    let mut f = ((texels / MAX_KEPT_TEXELS as f64).sqrt().floor() as usize).max(1);
    while w.div_ceil(f) * h.div_ceil(f) > MAX_KEPT_TEXELS {
        f += 1;
    }
    (w.div_ceil(f), h.div_ceil(f), f)
}

/// A uniform point (r1, r2) of the unit right triangle r1 + r2 ≤ 1 from two
/// uniform numbers in [0, 1), by folding the unit square.
fn unit_triangle_point(x: f64, y: f64) -> (f64, f64) {
    if x + y > 1.0 {
        (1.0 - x, 1.0 - y)
    } else {
        (x, y)
    }
}

/// `floor` to i64, saturating for huge or non-finite values (never panics).
fn floor_i64(x: f64) -> i64 {
    x.floor() as i64
}

/// Texel index for integer coordinate `i` under a wrap mode.
fn wrap(i: i64, n: usize, mode: WrappingMode) -> usize {
    let n64 = n as i64;
    match mode {
        WrappingMode::Repeat => i.rem_euclid(n64) as usize,
        WrappingMode::MirroredRepeat => {
            let m = i.rem_euclid(2 * n64);
            (if m >= n64 { 2 * n64 - 1 - m } else { m }) as usize
        }
        WrappingMode::ClampToEdge => i.clamp(0, n64 - 1) as usize,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LINEAR: Sampler = Sampler {
        wrap_s: WrappingMode::Repeat,
        wrap_t: WrappingMode::Repeat,
        nearest: false,
    };

    #[test]
    fn wrap_modes() {
        assert_eq!(wrap(-1, 4, WrappingMode::Repeat), 3);
        assert_eq!(wrap(5, 4, WrappingMode::Repeat), 1);
        assert_eq!(wrap(-1, 4, WrappingMode::MirroredRepeat), 0);
        assert_eq!(wrap(4, 4, WrappingMode::MirroredRepeat), 3);
        assert_eq!(wrap(9, 4, WrappingMode::MirroredRepeat), 1);
        assert_eq!(wrap(-7, 4, WrappingMode::ClampToEdge), 0);
        assert_eq!(wrap(i64::MAX, 4, WrappingMode::ClampToEdge), 3);
        assert!(wrap(i64::MIN, 4, WrappingMode::MirroredRepeat) < 4);
    }

    #[test]
    fn srgb_decode_known_values() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        // sRGB 0.5 is about 0.214 linear.
        assert!((srgb_to_linear(0.5) - 0.214_041).abs() < 1e-5);
    }

    #[test]
    fn mean_of_checker_over_whole_square_converges() {
        // 2×2 checker of 0 and 1: two triangles covering the square.
        let t = Texture::from_linear(2, 2, vec![[1.0; 3], [0.0; 3], [0.0; 3], [1.0; 3]]);
        let nearest = Sampler {
            nearest: true,
            ..LINEAR
        };
        let a = t.triangle_mean(
            [DVec2::ZERO, DVec2::new(1.0, 0.0), DVec2::new(1.0, 1.0)],
            &nearest,
        );
        let b = t.triangle_mean(
            [DVec2::ZERO, DVec2::new(1.0, 1.0), DVec2::new(0.0, 1.0)],
            &nearest,
        );
        // Each diagonal half covers half of both white cells: mean 0.5.
        assert!((a.x - 0.5).abs() < 0.03, "{a}");
        assert!((b.x - 0.5).abs() < 0.03, "{b}");
        // A triangle inside one cell sees only that cell.
        let c = t.triangle_mean(
            [
                DVec2::new(0.55, 0.05),
                DVec2::new(0.95, 0.05),
                DVec2::new(0.95, 0.45),
            ],
            &nearest,
        );
        assert_eq!(c, DVec3::ZERO);
        // Many repeats of the pattern: the mean tends to the texture mean.
        let d = t.triangle_mean(
            [DVec2::ZERO, DVec2::new(37.0, 0.0), DVec2::new(0.0, 41.0)],
            &LINEAR,
        );
        assert!((d.x - 0.5).abs() < 0.03, "{d}");
    }

    #[test]
    fn large_images_are_kept_box_filtered_within_the_cap() {
        assert_eq!(reduction(1024, 1024), (1024, 1024, 1));
        assert_eq!(reduction(8192, 8192), (1024, 1024, 8));
        let (kw, kh, f) = reduction(3000, 1001);
        assert!(kw * kh <= MAX_KEPT_TEXELS && f == 2, "{kw} {kh} {f}");
        assert_eq!(reduction(1 << 22, 1), (1 << 20, 1, 4));
        // Black for x < 1025, white beyond, 2049 × 1024: kept at f = 2
        // (1025 × 512), each block the mean of its texels (block 512 half
        // black, the last column of blocks one column of white), and the
        // mean over an area still that of the full image: the triangle
        // u + v ≤ 2 (repeat wrap) covers one whole tile, half white, and
        // the lower-left halves of two more, a quarter white each: 3/8.
        let img = image::RgbImage::from_fn(2049, 1024, |x, _| {
            image::Rgb(if x < 1025 { [0; 3] } else { [255; 3] })
        });
        let t = Texture::reduced(&image::DynamicImage::ImageRgb8(img)).unwrap();
        assert_eq!((t.width, t.height), (1025, 512));
        assert_eq!(t.bytes(), 1025 * 512 * 12);
        assert_eq!(t.texel(511, 0).x, 0.0);
        assert!((t.texel(512, 0).x - 0.5).abs() < 1e-6);
        assert!((t.texel(1024, 511).x - 1.0).abs() < 1e-6);
        let whole = t.triangle_mean(
            [DVec2::ZERO, DVec2::new(2.0, 0.0), DVec2::new(0.0, 2.0)],
            &LINEAR,
        );
        assert!((whole.x - 0.375).abs() < 0.01, "{whole}");
    }

    #[test]
    fn decode_checks_the_header_against_the_budget() {
        let mut png = Vec::new();
        image::DynamicImage::ImageLuma8(image::GrayImage::new(512, 512))
            .write_to(&mut Cursor::new(&mut png), image::ImageFormat::Png)
            .unwrap();
        // 256 KiB decoded and 3 MiB kept: fits 4 MiB, not 3 MiB, nor 4 MiB
        // with 1 MiB already held.
        assert!(Texture::decode(&png, 4 << 20, 0).is_ok());
        let e = Texture::decode(&png, 3 << 20, 0).unwrap_err();
        assert!(
            e.contains("512×512") && e.contains("budget of 3.0 MiB"),
            "{e}"
        );
        let e = Texture::decode(&png, 4 << 20, 1 << 20).unwrap_err();
        assert!(e.contains("besides the 1.0 MiB"), "{e}");
    }

    #[test]
    fn texture_transform_rotates_u_towards_v() {
        let t = UvTransform {
            offset: DVec2::new(0.5, 0.0),
            rotation: std::f64::consts::FRAC_PI_2,
            scale: DVec2::new(2.0, 1.0),
        };
        let p = t.apply(DVec2::new(1.0, 0.0));
        assert!((p - DVec2::new(0.5, 2.0)).length() < 1e-12, "{p}");
    }
}
