//! The film: per pixel sum, sum of squares and sample count.
//!
//! Sums are kept as fixed-point integers rather than floating point (64-bit in the film's compact cells,
//! 128-bit [`Pixel`]s for pixels that outgrow them), so accumulation is associative: the
//! image does not depend on the order in which samples arrive (threads, tiles), and two films of disjoint
//! sample ranges add up to exactly (bit for bit) the film of their union. Each sample value v is quantised
//! once to the integer q = round(v 2^32) (an i64: a fast conversion); the sum adds q and the sum of squares
//! adds floor(q^2 / 2^32), both exact integer operations. A sample whose value is not finite or whose
//! magnitude reaches [`MAX_SAMPLE_VALUE`] is discarded and counted, never accumulated.

mod cells;
pub mod checksum;
pub mod file;
pub mod output;

use glam::Vec3;

/// Fixed-point scale: one unit is 2^-32.
pub const FIXED_ONE: f64 = 4_294_967_296.0;
/// Samples at or beyond this magnitude (2^31) are treated as non-finite (keeps q = v 2^32 within an i64).
pub const MAX_SAMPLE_VALUE: f32 = 2_147_483_648.0;

/// Print the warning for a render that discarded samples (NaN, infinite, or at or beyond
/// [`MAX_SAMPLE_VALUE`]) to stderr, if it discarded any: the image lacks their light, so it is never
/// left silent (not even under `--quiet`).
pub fn warn_discarded(discarded: u64) {
    if discarded > 0 {
        errln!(
            "warning: {discarded} samples were discarded as NaN, infinite or beyond the film's range (2^31) and \
             are missing from the image; see README, \"Numerical robustness\""
        );
    }
}

/// Warn (on stderr) of crossings into a medium that rays could not keep: a fifth nested medium.
pub fn warn_lost_media(lost: u64) {
    if lost > 0 {
        errln!(
            "warning: {lost} ray crossings entered a fifth nested medium, beyond the 4 a ray keeps: inside it those \
             rays took the medium they were in (its absorption and index were lost); see scenes/README.md, \"Nested media\""
        );
    }
}

/// Brightest pixel means below this (2^-20) may be off by more than 2^-13 of their value: the film
/// rounds each sample to a multiple of 2^-32 ([`FIXED_ONE`]).
pub const DIM_PIXEL: f32 = 1.0 / 1_048_576.0;

/// Warn (on stderr) of an image so dim that the film's fixed point shows: every pixel 0 in a scene that
/// has light (below 2^-33 per sample it rounds to nothing), or a brightest pixel below [`DIM_PIXEL`]
/// (each sample is off by up to 2^-33, a relative error of 2^-33 / value: a trial's scene scaled by 1e-9
/// rendered 6.9% dark, by 1e-11 black). `lit`: the scene has a light, an emitter or a background.
/// Silent for a film without samples.
pub fn warn_dim(film: &Film, lit: bool) {
    if let Some(w) = dim_warning(film, lit) {
        errln!("warning: {w}");
    }
}

/// The text of [`warn_dim`]'s warning, if any.
pub fn dim_warning(film: &Film, lit: bool) -> Option<String> {
    if film.total_samples() == 0 || !lit {
        return None;
    }
    let brightest = (0..film.len()).map(|i| film.mean(i).abs().max_element()).fold(0.0f32, f32::max);
    let fix = "if the scene's light should be brighter, scale every radiance and intensity up by one factor (the image is linear)";
    if brightest == 0.0 {
        Some(format!(
            "every pixel of the image is 0: no light reached the camera (look for a quad or disk light facing away from the scene, a \
             light inside or on a surface, an emissive surface seen from its back, or shapes between the lights and all the camera \
             sees), or it was below the film's resolution (each sample is stored to 2^-32, 2.3e-10, so light below 1.2e-10 per sample \
             rounds to nothing); {fix}"
        ))
    } else if brightest < DIM_PIXEL {
        let off = 0.5 / FIXED_ONE / brightest as f64;
        Some(format!(
            "the brightest pixel is {brightest:.3e}: the film stores each sample to 2^-32 (2.3e-10), so that pixel can be off by up to \
             {:.2}% of its value and dimmer ones by more (2^-33 absolute); {fix}",
            off * 100.0
        ))
    } else {
        None
    }
}

/// Whether a sample may be accumulated: every channel finite and below [`MAX_SAMPLE_VALUE`] in
/// magnitude (`abs() < MAX` is false for NaN, so one comparison rejects NaN, infinities and huge values).
#[inline(always)]
pub fn valid_sample(a: [f32; 3]) -> bool {
    a.iter().all(|x| x.abs() < MAX_SAMPLE_VALUE)
}

/// [`valid_sample`] of 8 samples (channel rows `r`, `g`, `b`) as lane bits: the same comparison, in 8 lanes.
#[inline(always)]
pub fn valid_x8(r: &[f32; 8], g: &[f32; 8], b: &[f32; 8]) -> u32 {
    use wide::f32x8;
    let lim = f32x8::splat(MAX_SAMPLE_VALUE);
    let ok = |v: &[f32; 8]| f32x8::from(*v).abs().simd_lt(lim);
    (ok(r) & ok(g) & ok(b)).to_bitmask()
}

/// Samples below this magnitude in every channel (2^13) take the 64-bit path of accumulation
/// ([`square_fixed_x8`], [`Pixel::add_small_x8`]): their quantized values are at most 2^45 and the
/// squares' fixed-point values below 2^59, so 8 of each sum in an i64 without overflow.
pub const SMALL_SAMPLE_VALUE: f32 = 8192.0;

/// Lane bits of the samples (channel rows `r`, `g`, `b`) whose every channel is below
/// [`SMALL_SAMPLE_VALUE`] in magnitude (so also valid: NaN compares false).
#[inline(always)]
pub fn small_x8(r: &[f32; 8], g: &[f32; 8], b: &[f32; 8]) -> u32 {
    use wide::f32x8;
    let lim = f32x8::splat(SMALL_SAMPLE_VALUE);
    let ok = |v: &[f32; 8]| f32x8::from(*v).abs().simd_lt(lim);
    (ok(r) & ok(g) & ok(b)).to_bitmask()
}

/// `(q * q) >> 32` (the sum-of-squares term of [`Pixel::add_quantized`]) of 8 quantized values of
/// magnitude at most 2^45 ([`small_x8`] samples), in 64-bit lanes without a 128-bit product: with
/// |q| = h 2^32 + l, `floor(q^2 / 2^32) = h^2 2^32 + 2 h l + floor(l^2 / 2^32)` exactly (the first two
/// terms are whole multiples), and each product is of 32-bit factors (`vpmuludq`). Other lanes:
/// unspecified (never used).
#[inline(always)]
pub fn square_fixed_x8(q: &[i64; 8]) -> [i64; 8] {
    std::array::from_fn(|i| {
        let a = q[i].unsigned_abs();
        let (h, l) = (a >> 32, a & 0xffff_ffff);
        ((h * h) << 32).wrapping_add(2 * h * l).wrapping_add((l * l) >> 32) as i64
    })
}

/// The largest magnitude of one sample channel's fixed-point value ([`quantize`] of a valid sample):
/// the largest `f32` below [`MAX_SAMPLE_VALUE`] (2^31) is 2^31 - 2^7 (`f32`s in [2^30, 2^31) are
/// 2^7 apart), and `quantize` is odd and monotonic, so `|q| <= (2^31 - 2^7) 2^32 = 2^63 - 2^39`.
pub const MAX_QUANTIZED: i128 = (1 << 63) - (1 << 39);
/// The largest sum-of-squares term of one sample channel: `floor(MAX_QUANTIZED^2 / 2^32)` =
/// `(2^31 - 2^7)^2 2^32` (exact) `= 2^94 - 2^71 + 2^46`; the term is never negative.
pub const MAX_SQUARE_TERM: i128 = (1 << 94) - (1 << 71) + (1 << 46);

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Pixel {
    pub sum: [i128; 3],
    pub sum_sq: [i128; 3],
    pub count: u64,
}

/// The fixed-point value of one sample channel: `round(x 2^32)` (halves away from zero), exact for
/// `|x| < MAX_SAMPLE_VALUE` (`x 2^32` is exact in f64 and below 2^63).
#[inline(always)]
pub fn quantize(x: f32) -> i64 {
    (x as f64 * FIXED_ONE).round() as i64
}

/// [`quantize`] of 8 values at once, bit-identical for every `|x| < MAX_SAMPLE_VALUE` (other lanes are
/// unspecified): `t = trunc(y)`, then one step away from zero when `|y - t| >= 1/2` (`y - t` is exact),
/// which is `round`; two `f64x4` halves. The integral results become integers exactly: where every
/// `|y| < 2^50` (every sample below 2^18, nearly all), by the bits of `r + 1.5 2^52` (whose unit in the
/// last place is 1, so the sum is exact and its low bits are `r + 2^51`) minus those of `1.5 2^52`, two
/// vector operations on any x86-64 (AVX2 has no f64 -> i64 conversion: `trunc_int` is scalar there);
/// else by `trunc_int`.
#[inline(always)]
pub fn quantize_x8(x: &[f32; 8]) -> [i64; 8] {
    use wide::{f64x4, i64x4};
    const MAGIC: f64 = 6_755_399_441_055_744.0; // 1.5 * 2^52
    let mut out = [0i64; 8];
    for h in 0..2 {
        let y = f64x4::from(std::array::from_fn::<f64, 4, _>(|i| x[4 * h + i] as f64)) * f64x4::splat(FIXED_ONE);
        let t = y.trunc();
        let away = (y - t).abs().simd_ge(f64x4::splat(0.5));
        // +-1 with y's sign where the fraction reaches one half, else 0.
        let step = away & (f64x4::ONE | (y & f64x4::splat(-0.0)));
        let r = t + step;
        let q = if y.abs().simd_lt(f64x4::splat(1_125_899_906_842_624.0)).all() {
            bytemuck::cast::<f64x4, i64x4>(r + f64x4::splat(MAGIC)) - i64x4::splat(MAGIC.to_bits() as i64)
        } else {
            r.trunc_int()
        };
        out[4 * h..4 * h + 4].copy_from_slice(&q.to_array());
    }
    out
}

impl Pixel {
    /// Add one sample; returns false (and adds nothing) if it is non-finite or out of range.
    #[inline]
    pub fn add(&mut self, v: Vec3) -> bool {
        let a = v.to_array();
        if !valid_sample(a) {
            return false;
        }
        self.add_quantized(a.map(quantize));
        true
    }

    /// Add one valid sample already quantized per channel ([`quantize`]).
    #[inline(always)]
    pub fn add_quantized(&mut self, q: [i64; 3]) {
        for (c, &q) in q.iter().enumerate() {
            let q = q as i128;
            self.sum[c] += q;
            self.sum_sq[c] += (q * q) >> 32;
        }
        self.count += 1;
    }

    /// Add 8 valid quantized samples (`q[c]` = channel `c` of the 8): the sums of 8 calls of
    /// [`Pixel::add_quantized`], each channel summed in registers first (exact integers: the same sums).
    #[inline(always)]
    pub fn add_quantized_x8(&mut self, q: &[[i64; 8]; 3]) {
        for (c, row) in q.iter().enumerate() {
            let (mut s, mut s2) = (0i128, 0i128);
            for &q in row {
                let q = q as i128;
                s += q;
                s2 += (q * q) >> 32;
            }
            self.sum[c] += s;
            self.sum_sq[c] += s2;
        }
        self.count += 8;
    }

    /// Add 8 [`small_x8`] samples (`q[c]`, `sq[c]`: channel `c` of the 8, quantized and squared): the
    /// sums of 8 [`Pixel::add_quantized`] calls. Each channel's 8 values are summed in an i64 first
    /// (below 2^48 and 2^62: no overflow).
    #[inline(always)]
    pub fn add_small_x8(&mut self, q: &[[i64; 8]; 3], sq: &[[i64; 8]; 3]) {
        for c in 0..3 {
            self.sum[c] += q[c].iter().sum::<i64>() as i128;
            self.sum_sq[c] += sq[c].iter().sum::<i64>() as i128;
        }
        self.count += 8;
    }

    /// Add `o`'s sums and count to this pixel's. An overflow panics (never a silent wrap); pixels of
    /// films that read ([`Pixel::inconsistency`] holds them to `|sum| <= count MAX_QUANTIZED` and
    /// `0 <= sum_sq <= count MAX_SQUARE_TERM`, `count <= 2^32 - 1` each) cannot reach it: those bounds
    /// add up, so a sum of pixels of `n` samples in all has `|sum| <= n (2^63 - 2^39) < 2^127` for any
    /// `n < 2^64` (the count overflows first) and `sum_sq <= n (2^94 - 2^71 + 2^46) < 2^127` for any
    /// `n < 2^33`: the merge of films of disjoint ranges of one render (`n <= spp < 2^32`), or of
    /// fewer than 2 films' worth of 2^32 samples per pixel. [`Pixel::checked_merged`] says so instead.
    #[inline]
    pub fn merge(&mut self, o: &Pixel) {
        *self = self.checked_merged(o).unwrap_or_else(|| panic!("pixel sums overflow: {self:?} + {o:?}"));
    }

    /// `self` plus `o` (sums and count), or `None` where a sum or the count overflows.
    #[inline]
    pub fn checked_merged(&self, o: &Pixel) -> Option<Pixel> {
        let mut out = *self;
        for c in 0..3 {
            out.sum[c] = self.sum[c].checked_add(o.sum[c])?;
            out.sum_sq[c] = self.sum_sq[c].checked_add(o.sum_sq[c])?;
        }
        out.count = self.count.checked_add(o.count)?;
        Some(out)
    }

    /// What makes this pixel one that no `count` samples can give, or that holds more samples than
    /// `samples` (those its film's completed work units hold), if anything: a pixel read from a film is
    /// held to it. Each sample channel adds `q` with `|q| <= MAX_QUANTIZED` to `sum` and
    /// `floor(q^2 / 2^32)`, between 0 and [`MAX_SQUARE_TERM`], to `sum_sq` (see [`MAX_QUANTIZED`]), so
    /// `|sum| <= count MAX_QUANTIZED` and `0 <= sum_sq <= count MAX_SQUARE_TERM` (a pixel of no
    /// samples sums to 0). Its count may be below `samples`: samples discarded as non-finite or out
    /// of range are not counted ([`warn_discarded`]).
    #[inline]
    pub fn inconsistency(&self, samples: u64) -> Option<String> {
        // The test of a valid pixel, without branches or overflow checks: counts below 2^32 (every
        // film's: its range holds at most 2^32 - 1 samples) bound the sums by plain products in 128
        // bits (`n MAX_QUANTIZED < 2^95`, `n MAX_SQUARE_TERM < 2^126`), and a negative sum of squares
        // taken as unsigned is at least 2^127, beyond its bound. Any other pixel is judged exactly by
        // `explain`, which says what is wrong (or finds nothing: a count of 2^32 or more that holds).
        let n = self.count;
        let nq = n as u128 * MAX_QUANTIZED as u128;
        let nsq = (n & 0xffff_ffff) as u128 * MAX_SQUARE_TERM as u128;
        let mut ok = (n <= samples) & (n >> 32 == 0);
        for c in 0..3 {
            ok &= (self.sum[c].unsigned_abs() <= nq) & ((self.sum_sq[c] as u128) <= nsq);
        }
        if ok {
            return None;
        }
        self.explain(samples)
    }

    #[cold]
    fn explain(&self, samples: u64) -> Option<String> {
        let n = self.count;
        let of = |n: u64| if n == 1 { "1 sample".to_string() } else { format!("{n} samples") };
        if n > samples {
            return Some(format!("{}, but the film's completed work units hold {} for it", of(n), of(samples)));
        }
        for (name, (&s, &s2)) in ["red", "green", "blue"].iter().zip(self.sum.iter().zip(&self.sum_sq)) {
            let what = |m: &str, v: i128| format!("{name} {m} {v} (in units of 2^-32)");
            if n == 0 && (s != 0 || s2 != 0) {
                let m = if s != 0 { what("sum", s) } else { what("sum of squares", s2) };
                return Some(format!("{m} with no samples (a pixel of no samples sums to 0)"));
            }
            if s.unsigned_abs() > (n as i128 * MAX_QUANTIZED) as u128 {
                return Some(format!(
                    "{} is beyond what {} can give (|sum| <= {n} x (2^63 - 2^39) = {})",
                    what("sum", s),
                    of(n),
                    n as i128 * MAX_QUANTIZED
                ));
            }
            if s2 < 0 {
                return Some(format!("{} is negative", what("sum of squares", s2)));
            }
            if s2 > (n as i128).saturating_mul(MAX_SQUARE_TERM) {
                return Some(format!(
                    "{} is beyond what {} can give (<= {n} x (2^94 - 2^71 + 2^46) = {})",
                    what("sum of squares", s2),
                    of(n),
                    (n as i128).saturating_mul(MAX_SQUARE_TERM)
                ));
            }
        }
        None
    }

    /// Mean radiance (zero for a pixel with no samples).
    #[inline]
    pub fn mean(&self) -> Vec3 {
        mean_of(self.sum.map(|s| s as f64), self.count)
    }

    /// Unbiased sample variance of the mean estimate per channel (variance / n).
    pub fn variance_of_mean(&self) -> Vec3 {
        if self.count < 2 {
            return Vec3::ZERO;
        }
        let n = self.count as f64;
        let mut out = [0.0f32; 3];
        for (c, o) in out.iter_mut().enumerate() {
            let s = self.sum[c] as f64 / FIXED_ONE;
            let s2 = self.sum_sq[c] as f64 / FIXED_ONE;
            *o = (((s2 - s * s / n) / (n - 1.0)).max(0.0) / n) as f32;
        }
        Vec3::from_array(out)
    }
}

/// One pixel as the film stores it: the sums of a [`Pixel`] in 64 bits each and its count in 32, one
/// cache line (half of a `Pixel`: half the memory, the page faults of a new film and the lines the
/// accumulate stage touches). A pixel whose sums would leave that range (in units of 2^-32: a sum of
/// squared samples reaching 2^31, e.g. radiance 1,000 over 2,000 samples or 100 over 200,000, or more
/// than 2^32 samples) moves to the film's side table of [`Pixel`]s, and
/// `wide` is then its index there plus one. Either way the stored values are exact, so the film is the
/// same whatever the order of additions.
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C, align(64))]
struct Cell {
    sum: [i64; 3],
    sum_sq: [i64; 3],
    count: u32,
    wide: u32,
    /// (Explicit, so that the 64-byte cell has no implicit padding: `Pod`.)
    pad: [u32; 2],
}

/// Bytes the film takes per pixel (pixels moved to the side table take a [`Pixel`] more).
pub const FILM_BYTES_PER_PIXEL: usize = std::mem::size_of::<Cell>();

impl Cell {
    /// `self` plus `p` as a compact cell, or `None` when a sum or the count leaves the cell's range.
    #[inline(always)]
    fn checked_add(&self, p: &Pixel) -> Option<Cell> {
        // Every sum in 128 bits, then one test of all the ranges (no branch per value).
        let mut out = *self;
        let mut ok = true;
        let mut add = |a: i64, b: i128| -> i64 {
            let (s, over) = (a as i128).overflowing_add(b);
            ok &= !over & (s as i64 as i128 == s);
            s as i64
        };
        for c in 0..3 {
            out.sum[c] = add(self.sum[c], p.sum[c]);
            out.sum_sq[c] = add(self.sum_sq[c], p.sum_sq[c]);
        }
        let (n, over) = p.count.overflowing_add(self.count as u64);
        out.count = n as u32;
        (ok & !over & (n >> 32 == 0)).then_some(out)
    }

    fn to_pixel(self) -> Pixel {
        Pixel { sum: self.sum.map(i128::from), sum_sq: self.sum_sq.map(i128::from), count: self.count as u64 }
    }

    /// [`Pixel::mean`] of [`Cell::to_pixel`], from the 64-bit sums (each converts to the same `f64`
    /// as its 128-bit widening: without the 128-bit pixel and its software conversions).
    #[inline]
    fn mean(&self) -> Vec3 {
        mean_of(self.sum.map(|s| s as f64), self.count as u64)
    }
}

/// The mean radiance of sums `sum` (in units of 2^-32, converted to `f64`) over `count` samples (zero
/// for none).
#[inline]
fn mean_of(sum: [f64; 3], count: u64) -> Vec3 {
    if count == 0 {
        return Vec3::ZERO;
    }
    let n = count as f64 * FIXED_ONE;
    Vec3::new((sum[0] / n) as f32, (sum[1] / n) as f32, (sum[2] / n) as f32)
}

/// Per pixel sums of a render (row-major), exact integers whatever the order of additions (see the
/// module doc). Pixels are read as [`Pixel`]s ([`Film::pixel`], [`Film::pixels`]); the storage is
/// compact ([`FILM_BYTES_PER_PIXEL`]).
#[derive(Clone, Debug)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    cells: cells::Cells<Cell>,
    /// Pixels whose sums left the 64-bit range (`Cell::wide` - 1 indexes here).
    wide: Vec<Pixel>,
}

/// Films are equal when every pixel's sums and count are (however each is stored).
impl PartialEq for Film {
    fn eq(&self, o: &Film) -> bool {
        (self.width, self.height) == (o.width, o.height) && self.pixels().eq(o.pixels())
    }
}

impl Eq for Film {}

impl Film {
    pub fn new(width: u32, height: u32) -> Film {
        Film::with_cells(width, height, cells::Cells::<Cell>::zeroed(width as usize * height as usize))
    }

    /// [`Film::new`], or an error saying how much memory it needs where that cannot be had (where
    /// `new` aborts the process): films read for resume and merge, and checkpoints' copies.
    pub fn try_new(width: u32, height: u32) -> Result<Film, String> {
        let n = width as usize * height as usize;
        match cells::Cells::<Cell>::try_zeroed(n) {
            Some(cells) => Ok(Film::with_cells(width, height, cells)),
            None => Err(format!(
                "not enough memory for the film of {width}x{height} pixels: it needs {} bytes ({FILM_BYTES_PER_PIXEL} per pixel)",
                n as u128 * FILM_BYTES_PER_PIXEL as u128
            )),
        }
    }

    fn with_cells(width: u32, height: u32, mut cells: cells::Cells<Cell>) -> Film {
        // The pages come untouched (zero pages of the OS): touch every page now, once, rather than in
        // the render, where each first write would fault inside the accumulate stage with the film
        // locked (~1.5 us a 4 KiB page here; one fault per 2 MiB where huge pages are given).
        for c in cells.iter_mut().step_by(4096 / FILM_BYTES_PER_PIXEL) {
            std::hint::black_box(c).wide = 0;
        }
        Film { width, height, cells, wide: Vec::new() }
    }

    /// Make this film a copy of `o` (of the same size), in the memory it has: a copy, no allocation
    /// beyond the side table of wide pixels.
    pub fn copy_from(&mut self, o: &Film) {
        assert_eq!((self.width, self.height), (o.width, o.height));
        self.cells.copy_from_slice(&o.cells);
        self.wide.clone_from(&o.wide);
    }

    /// Number of pixels.
    pub fn len(&self) -> usize {
        self.width as usize * self.height as usize
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Pixel `i` (row-major).
    #[inline]
    pub fn pixel(&self, i: usize) -> Pixel {
        match self.cells[i] {
            c @ Cell { wide: 0, .. } => c.to_pixel(),
            Cell { wide, .. } => self.wide[wide as usize - 1],
        }
    }

    /// Every pixel, row-major.
    pub fn pixels(&self) -> impl ExactSizeIterator<Item = Pixel> + '_ {
        (0..self.len()).map(|i| self.pixel(i))
    }

    /// Ask the cache for pixel `i`'s cell ahead of a [`Film::merge_pixel`] (a hint: no effect on the
    /// film; out-of-range `i` is ignored).
    #[inline(always)]
    pub fn prefetch(&self, i: usize) {
        #[cfg(target_arch = "x86_64")]
        if let Some(c) = self.cells.get(i) {
            // SAFETY: a prefetch reads nothing architecturally; the pointer is to a live cell.
            unsafe { std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>((c as *const Cell).cast()) };
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = i;
    }

    /// Add `p`'s sums and count to pixel `i`.
    #[inline(always)]
    pub fn merge_pixel(&mut self, i: usize, p: &Pixel) {
        let cell = &mut self.cells[i];
        if cell.wide == 0 {
            if let Some(sum) = cell.checked_add(p) {
                *cell = sum;
                return;
            }
        }
        self.merge_wide(i, p);
    }

    /// [`Film::merge_pixel`] of a pixel in (or moving to) the side table.
    #[cold]
    #[inline(never)]
    fn merge_wide(&mut self, i: usize, p: &Pixel) {
        if !self.merge_wide_checked(i, p) {
            panic!("pixel {i}: sums overflow: {:?} + {p:?}", self.pixel(i));
        }
    }

    /// [`Film::merge_wide`], or false (the pixel unchanged) where a sum or the count would overflow.
    #[cold]
    #[inline(never)]
    fn merge_wide_checked(&mut self, i: usize, p: &Pixel) -> bool {
        let Some(sum) = self.pixel(i).checked_merged(p) else { return false };
        let cell = &mut self.cells[i];
        if cell.wide == 0 {
            self.wide.push(sum);
            cell.wide = u32::try_from(self.wide.len()).expect("at most 2^32 - 1 wide pixels");
        } else {
            self.wide[cell.wide as usize - 1] = sum;
        }
        true
    }

    /// [`Film::merge_pixel`], or false (the pixel unchanged) where a sum or the count would overflow:
    /// films read from files ([`file::FilmReader::merge_into`]), which make that an error.
    #[inline(always)]
    pub fn try_merge_pixel(&mut self, i: usize, p: &Pixel) -> bool {
        let cell = &mut self.cells[i];
        if cell.wide == 0 {
            if let Some(sum) = cell.checked_add(p) {
                *cell = sum;
                return true;
            }
        }
        self.merge_wide_checked(i, p)
    }

    /// Make pixel `i` exactly `p`.
    pub fn set_pixel(&mut self, i: usize, p: Pixel) {
        let cell = &mut self.cells[i];
        if cell.wide != 0 {
            self.wide[cell.wide as usize - 1] = p;
        } else {
            *cell = Cell::default();
            self.merge_pixel(i, &p);
        }
    }

    /// Pixel `i`'s mean radiance ([`Pixel::mean`] of [`Film::pixel`]).
    #[inline]
    pub fn mean(&self, i: usize) -> Vec3 {
        match &self.cells[i] {
            c @ Cell { wide: 0, .. } => c.mean(),
            Cell { wide, .. } => self.wide[*wide as usize - 1].mean(),
        }
    }

    /// Linear radiance, row-major RGB: every pixel's mean.
    pub fn to_rgb(&self) -> Vec<Vec3> {
        (0..self.len()).map(|i| self.mean(i)).collect()
    }

    pub fn merge(&mut self, o: &Film) {
        assert_eq!((self.width, self.height), (o.width, o.height));
        for (i, p) in o.pixels().enumerate() {
            self.merge_pixel(i, &p);
        }
    }

    /// Samples in all. Checked (an overflow panics, never wraps): films read are held to at most
    /// 2^32 - 1 samples per pixel of their range, so a merge of one render's disjoint ranges totals at
    /// most `MAX_PIXELS (2^32 - 1) < 2^58`.
    pub fn total_samples(&self) -> u64 {
        self.cells
            .iter()
            .map(|c| if c.wide == 0 { c.count as u64 } else { self.wide[c.wide as usize - 1].count })
            .try_fold(0u64, u64::checked_add)
            .expect("the film's sample count overflows 64 bits")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Eight `add_quantized` calls, lane by lane.
    fn by_lane(q: &[[i64; 8]; 3]) -> Pixel {
        let mut p = Pixel::default();
        (0..8).for_each(|l| p.add_quantized([q[0][l], q[1][l], q[2][l]]));
        p
    }

    /// The 8-lane validity bits equal `valid_sample` lane by lane (NaN, infinities, the limit and
    /// just below it, both signs, random magnitudes); `add_quantized_x8` equals 8 `add_quantized` calls
    /// (extreme magnitudes of both signs included).
    #[test]
    fn valid_x8_and_add_quantized_x8_match_scalar() {
        let special = [0.0, -0.0, 1.0, -1.0, f32::NAN, -f32::NAN, f32::INFINITY, f32::NEG_INFINITY, MAX_SAMPLE_VALUE, -MAX_SAMPLE_VALUE];
        let edge = [MAX_SAMPLE_VALUE.next_down(), -MAX_SAMPLE_VALUE.next_down(), 1e-45, f32::MAX];
        let vals: Vec<f32> = special.iter().chain(&edge).copied().collect();
        let mut next = crate::sample::hash::test_uniforms(0x7a11d);
        let (mut valid, mut invalid) = (0, 0);
        for round in 0..4000 {
            let mut pick = || {
                let u = next();
                if u < 0.3 {
                    vals[(next() * vals.len() as f32) as usize % vals.len()]
                } else {
                    (u - 0.65) * 2.4 * MAX_SAMPLE_VALUE * [1e-9, 1.0][round % 2]
                }
            };
            let rows: [[f32; 8]; 3] = std::array::from_fn(|_| std::array::from_fn(|_| pick()));
            let bits = valid_x8(&rows[0], &rows[1], &rows[2]);
            for (l, ((&x, &y), &z)) in rows[0].iter().zip(&rows[1]).zip(&rows[2]).enumerate() {
                let want = valid_sample([x, y, z]);
                assert_eq!(bits >> l & 1 != 0, want, "{:?}", [x, y, z]);
                (valid, invalid) = (valid + want as u32, invalid + !want as u32);
            }
            if bits == 0xff {
                let q = rows.map(|r| quantize_x8(&r));
                let mut a = Pixel::default();
                a.add_quantized_x8(&q);
                assert_eq!(a, by_lane(&q));
            }
        }
        let max = quantize(MAX_SAMPLE_VALUE.next_down());
        let q = [[max; 8], [-max; 8], [max, -max, max, -max, 0, 1, -1, max]];
        let mut a = Pixel::default();
        a.add_quantized_x8(&q);
        assert_eq!(a, by_lane(&q));
        assert!(valid > 3000 && invalid > 3000, "{valid} valid, {invalid} invalid");
    }

    /// The film's compact cells hold exactly what 128-bit pixels hold: runs merged into a film and into
    /// plain `Pixel`s agree pixel by pixel while sums cross the 64-bit range in either direction (up to
    /// i64::MAX and past it, down to i64::MIN and past it), sums of squares do, and counts pass u32::MAX;
    /// pixels that moved to the side table keep merging there; films equal in value are equal however
    /// their pixels are stored; `set_pixel` replaces compact and wide pixels alike.
    #[test]
    fn compact_cells_hold_exact_sums_and_move_wide_pixels_aside() {
        let max = i64::MAX as i128;
        let runs: [Pixel; 6] = [
            Pixel { sum: [max - 5, -max, 1], sum_sq: [3, 0, 1], count: 2 },
            Pixel { sum: [5, -1, -2], sum_sq: [0, 1, 1], count: 1 },
            Pixel { sum: [0, -1, 0], sum_sq: [0, 0, 0], count: 1 },
            Pixel { sum: [1, 7, 1], sum_sq: [max, 0, 2], count: 1 },
            Pixel { sum: [-(max + 3), 0, 0], sum_sq: [1, 0, 0], count: u32::MAX as u64 },
            Pixel { sum: [1 << 100, 0, -1], sum_sq: [1 << 90, 1, 1], count: 3 },
        ];
        let mut film = Film::new(4, 2);
        let mut want = vec![Pixel::default(); 8];
        let mut next = crate::sample::hash::test_uniforms(0xf11);
        for step in 0..400 {
            let i = (next() * 8.0) as usize % 8;
            let r = runs[(next() * 6.0) as usize % 6];
            film.merge_pixel(i, &r);
            want[i].merge(&r);
            assert_eq!(film.pixel(i), want[i], "step {step}, pixel {i}");
        }
        assert!(film.pixels().eq(want.iter().copied()));
        // Some pixels moved, each at most once (8 pixels).
        let moved = film.wide.len();
        assert!(moved > 0 && moved <= 8, "{moved} pixels moved to the side table");
        // The same values stored compactly (a film built by set_pixel from small values) compare equal.
        let mut a = Film::new(2, 1);
        let mut b = Film::new(2, 1);
        a.merge_pixel(0, &Pixel { sum: [max, 0, 0], sum_sq: [0; 3], count: 1 });
        a.merge_pixel(0, &Pixel { sum: [1, 0, 0], sum_sq: [0; 3], count: 1 });
        a.merge_pixel(0, &Pixel { sum: [-max, 0, 0], sum_sq: [0; 3], count: 1 });
        assert_eq!(a.wide.len(), 1);
        b.set_pixel(0, Pixel { sum: [1, 0, 0], sum_sq: [0; 3], count: 3 });
        assert_eq!(b.wide.len(), 0);
        assert_eq!(a, b);
        b.set_pixel(1, Pixel { sum: [2, 0, 0], sum_sq: [0; 3], count: 1 });
        assert_ne!(a, b);
        a.set_pixel(0, Pixel { sum: [-4, 0, 0], sum_sq: [0; 3], count: 9 });
        assert_eq!(a.pixel(0), Pixel { sum: [-4, 0, 0], sum_sq: [0; 3], count: 9 });
        assert_eq!(FILM_BYTES_PER_PIXEL, 64);
    }

    /// The 64-bit path of small samples equals `add_quantized`'s 128-bit one: `small_x8` admits exactly
    /// the samples below SMALL_SAMPLE_VALUE in every channel (the limit and its neighbours, NaN,
    /// infinities, both signs), `square_fixed_x8` equals `(q * q) >> 32` on every admitted magnitude
    /// (zero, the largest, every power of two and its neighbours, random bits), and `add_small_x8`
    /// gives the pixel of 8 `add_quantized` calls (the largest values in all 8 lanes too).
    #[test]
    fn small_samples_take_an_exact_64_bit_path() {
        let lim = SMALL_SAMPLE_VALUE;
        let edge = [lim, -lim, lim.next_down(), -lim.next_down(), lim.next_up(), f32::NAN, f32::INFINITY, 0.0, -0.0];
        for (i, &v) in edge.iter().enumerate() {
            let row = |c: usize| -> [f32; 8] { std::array::from_fn(|l| if l == c { v } else { 1.0 }) };
            let bits = small_x8(&row(0), &row(1), &row(2));
            let want = v.abs() < lim;
            assert_eq!(bits, if want { 0xff } else { 0xff & !0b111 }, "value {i}: {v}");
        }
        let qmax = quantize(lim.next_down());
        assert!(qmax <= 1 << 45);
        let mut qs: Vec<i64> = vec![0, 1, -1, qmax, -qmax, (1 << 32) - 1, 1 << 32, (1 << 32) + 1];
        for k in 0..46 {
            qs.extend([(1i64 << k) - 1, 1 << k, -(1 << k), (1 << k) + 1].iter().filter(|q| q.unsigned_abs() <= qmax as u64));
        }
        let mut next = crate::sample::hash::test_uniforms(0x5a11);
        qs.extend((0..4000).map(|_| ((next() as f64 - 0.5) * 2.0 * qmax as f64) as i64));
        for c in qs.chunks(8) {
            let q: [i64; 8] = std::array::from_fn(|l| c[l % c.len()]);
            let sq = square_fixed_x8(&q);
            for l in 0..8 {
                assert_eq!(sq[l] as i128, (q[l] as i128 * q[l] as i128) >> 32, "q = {}", q[l]);
            }
            let rows = [q, q.map(|x| -x), q.map(|x| x / 3)];
            let sqs = rows.map(|r| square_fixed_x8(&r));
            let mut a = Pixel::default();
            a.add_small_x8(&rows, &sqs);
            assert_eq!(a, by_lane(&rows));
        }
        let rows = [[qmax; 8], [-qmax; 8], [qmax, -qmax, qmax, -qmax, 0, 1, -1, qmax]];
        let mut a = Pixel::default();
        a.add_small_x8(&rows, &rows.each_ref().map(square_fixed_x8));
        assert_eq!(a, by_lane(&rows));
    }

    /// The 8-lane quantization equals the scalar one on every kind of valid value: exact halves of the
    /// 2^-32 grid (the rounding ties, both signs), values just beside them, subnormals, zeros of both
    /// signs, the largest valid magnitude, and random values at every exponent.
    #[test]
    fn quantize_x8_matches_scalar() {
        let mut vals: Vec<f32> = vec![0.0, -0.0, f32::MIN_POSITIVE, -f32::MIN_POSITIVE, 1e-45, -1e-45, 1.0, -1.0];
        vals.push(MAX_SAMPLE_VALUE.next_down());
        vals.push(-MAX_SAMPLE_VALUE.next_down());
        for k in 0..40 {
            // (2k + 1) / 2^33: exactly half-way between two 2^-32 steps.
            let tie = (2 * k + 1) as f32 / (1u64 << 33) as f32;
            for v in [tie, tie.next_up(), tie.next_down()] {
                vals.extend([v, -v]);
            }
        }
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for _ in 0..20_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let v = f32::from_bits((state >> 32) as u32);
            if v.abs() < MAX_SAMPLE_VALUE {
                vals.push(v);
            }
        }
        // Both ends of the exact integer path (every |x| < 2^18) and just past it.
        let edge = 262_144.0f32;
        for v in [edge.next_down(), edge, edge.next_up(), 131_072.0, 131_072.0f32.next_down()] {
            vals.extend([v, -v]);
        }
        // As drawn (chunks mixing magnitudes: mostly the `trunc_int` path), then the values below
        // 2^18 alone (every chunk on the integer-bits path), each shuffled by a fixed stride.
        let small: Vec<f32> = vals.iter().copied().filter(|v| v.abs() < edge).collect();
        let mut ties = 0;
        let mut fast_chunks = 0;
        for set in [&vals, &small] {
            for start in 0..3 {
                let order: Vec<f32> = (0..set.len()).map(|i| set[(i * 7 + start) % set.len()]).collect();
                for chunk in order.chunks_exact(8) {
                    let x: [f32; 8] = chunk.try_into().unwrap();
                    let got = quantize_x8(&x);
                    fast_chunks += x.iter().all(|v| v.abs() < edge) as usize;
                    for l in 0..8 {
                        assert_eq!(got[l], quantize(x[l]), "x = {:e} ({:#x})", x[l], x[l].to_bits());
                        ties += ((x[l] as f64 * FIXED_ONE).fract().abs() == 0.5) as usize;
                    }
                }
            }
        }
        assert!(vals.len() > 10_000 && small.len() > 5_000 && ties >= 70, "{} values, {} small, {ties} ties", vals.len(), small.len());
        assert!(fast_chunks > 1_500, "{fast_chunks} chunks on the integer-bits path");
    }

    #[test]
    fn fixed_point_sums_are_order_independent_and_exact() {
        let vals: Vec<Vec3> = (0..1000).map(|i| Vec3::splat(((i * 7919) % 1000) as f32 / 333.0 + 1e-3)).collect();
        let mut a = Pixel::default();
        vals.iter().for_each(|v| assert!(a.add(*v)));
        let mut b = Pixel::default();
        vals.iter().rev().for_each(|v| assert!(b.add(*v)));
        assert_eq!(a, b);
        let (mut c, mut d) = (Pixel::default(), Pixel::default());
        vals[..400].iter().for_each(|v| assert!(c.add(*v)));
        vals[400..].iter().for_each(|v| assert!(d.add(*v)));
        c.merge(&d);
        assert_eq!(a, c);
        let mean: f64 = vals.iter().map(|v| v.x as f64).sum::<f64>() / 1000.0;
        assert!((a.mean().x as f64 - mean).abs() < 1e-6);
    }

    /// The bounds a film's pixels are held to are those of the quantisation, exactly: the largest valid
    /// sample channel (scalar and 8-lane quantisation alike) gives `MAX_QUANTIZED` and the square term
    /// `MAX_SQUARE_TERM`, so a pixel of `n` such samples (either sign) sits on its bounds and is
    /// consistent, and one unit more is not; `n` samples is consistent with `n` or more held, not fewer.
    #[test]
    fn pixel_bounds_are_the_quantisations() {
        let top = MAX_SAMPLE_VALUE.next_down();
        assert_eq!(top as f64, 2f64.powi(31) - 128.0);
        assert_eq!(quantize(top) as i128, MAX_QUANTIZED);
        assert_eq!(quantize(-top) as i128, -MAX_QUANTIZED);
        assert_eq!(quantize_x8(&[top; 8]), [MAX_QUANTIZED as i64; 8]);
        assert_eq!((MAX_QUANTIZED * MAX_QUANTIZED) >> 32, MAX_SQUARE_TERM);
        let mut p = Pixel::default();
        for k in 0..5u64 {
            assert_eq!(p.inconsistency(k), None);
            assert!(p.add(Vec3::new(top, -top, 0.0)));
        }
        assert_eq!(p.sum, [5 * MAX_QUANTIZED, -5 * MAX_QUANTIZED, 0]);
        assert_eq!(p.sum_sq, [5 * MAX_SQUARE_TERM, 5 * MAX_SQUARE_TERM, 0]);
        assert_eq!(p.inconsistency(5), None);
        assert_eq!(p.inconsistency(4).unwrap(), "5 samples, but the film's completed work units hold 4 samples for it");
        for (c, d) in [(0, 1), (1, -1)] {
            let mut q = p;
            q.sum[c] += d;
            assert!(q.inconsistency(5).unwrap().contains("sum") && q.inconsistency(5).unwrap().contains("beyond what 5 samples"));
            let mut q = p;
            q.sum_sq[c] += 1;
            assert!(q.inconsistency(5).unwrap().contains("sum of squares"));
        }
    }

    /// Merging pixels adds with checks: an overflow of a sum, a sum of squares or the count is `None`
    /// (`checked_merged`) or a panic (`merge`, `Film::merge_pixel`), never a wrap (the reviewer's films
    /// of sums 1.5 2^126 merged to -4.95e27).
    #[test]
    fn pixel_merges_never_wrap() {
        let big = Pixel { sum: [3 << 125, 0, 0], sum_sq: [0; 3], count: 2 };
        assert_eq!(big.checked_merged(&big), None);
        let sq = Pixel { sum: [0; 3], sum_sq: [0, 0, i128::MAX], count: 1 };
        assert_eq!(sq.checked_merged(&Pixel { sum_sq: [0, 0, 1], ..Pixel::default() }), None);
        let n = Pixel { count: u64::MAX, ..Pixel::default() };
        assert_eq!(n.checked_merged(&Pixel { count: 1, ..Pixel::default() }), None);
        assert_eq!(big.checked_merged(&Pixel::default()), Some(big));
        let neg = Pixel { sum: [-(3 << 125), 0, 0], sum_sq: [0; 3], count: 2 };
        assert_eq!(big.checked_merged(&neg), Some(Pixel { sum: [0; 3], sum_sq: [0; 3], count: 4 }));
        for (a, b) in [(big, big), (n, Pixel { count: 1, ..Pixel::default() })] {
            assert!(std::panic::catch_unwind(|| {
                let mut a = a;
                a.merge(&b)
            })
            .is_err());
            let mut film = Film::new(1, 1);
            film.set_pixel(0, a);
            assert!(!film.try_merge_pixel(0, &b));
            assert_eq!(film.pixel(0), a);
            assert!(std::panic::catch_unwind(move || film.merge_pixel(0, &b)).is_err());
        }
    }

    #[test]
    fn non_finite_samples_are_rejected() {
        let mut p = Pixel::default();
        assert!(!p.add(Vec3::new(f32::NAN, 0.0, 0.0)));
        assert!(!p.add(Vec3::new(0.0, f32::INFINITY, 0.0)));
        assert!(!p.add(Vec3::splat(2.2e9)));
        assert!(p.add(Vec3::splat(2.1e9)));
        assert_eq!(p.count, 1);
        p = Pixel::default();
        assert_eq!(p.count, 0);
        assert_eq!(p.mean(), Vec3::ZERO);
    }

    #[test]
    fn variance_matches_direct_formula() {
        let mut p = Pixel::default();
        let xs = [0.5f32, 1.5, 2.0, 4.0];
        xs.iter().for_each(|&x| {
            p.add(Vec3::splat(x));
        });
        let m = 2.0f64;
        let var = xs.iter().map(|&x| (x as f64 - m).powi(2)).sum::<f64>() / 3.0 / 4.0;
        assert!((p.variance_of_mean().x as f64 - var).abs() < 1e-6);
    }
}
