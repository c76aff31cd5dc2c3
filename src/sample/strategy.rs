//! The five sampling strategies and the 1D / 2D sample functions (see the module doc of `sample` for the
//! semantics and conventions).

use super::hash::{
    permute, permute_pow2, permute_runs, permute_x8, random_2d_keyed, random_bits, random_f32_keyed, stream_key, PermutePow2, PermuteShape,
    ONE_MINUS_EPSILON, RUN_MAX,
};
use super::sobol::{sobol_owen_1d, sobol_owen_2d};
use crate::simd::{f32x8, LANES};

/// How the `n` samples of one integral are placed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Strategy {
    /// Always the centre of the domain: one deterministic sample repeated (pinhole lens, pixel centre).
    /// (`centre` is accepted in files as on the command line.)
    #[serde(alias = "centre")]
    Center,
    /// Centres of an `nx x ny` grid of sub-squares: a deterministic midpoint quadrature rule.
    Grid,
    /// Independent uniform points.
    Random,
    /// One uniform point in each of the `nx x ny` strata (for counts neither square nor a power of two,
    /// in each of `n` equal-area strata in rows: [`jitter_rows`]).
    Jittered,
    /// Owen-scrambled, index-shuffled Sobol (0,2)-sequence.
    Sobol,
}

impl Strategy {
    /// Every strategy, in increasing order of sophistication.
    pub const ALL: [Strategy; 5] = [Strategy::Center, Strategy::Grid, Strategy::Random, Strategy::Jittered, Strategy::Sobol];

    /// The lowercase name, as used in scene files and on the command line (same as serde).
    pub fn name(self) -> &'static str {
        match self {
            Strategy::Center => "center",
            Strategy::Grid => "grid",
            Strategy::Random => "random",
            Strategy::Jittered => "jittered",
            Strategy::Sobol => "sobol",
        }
    }

    /// Parse a name: exact and lowercase, as in profile files; `"centre"` is accepted for `Center`.
    pub fn parse(s: &str) -> Option<Strategy> {
        if s == "centre" {
            return Some(Strategy::Center);
        }
        Strategy::ALL.into_iter().find(|st| st.name() == s)
    }

    /// [`Strategy::parse`], or the error a user sees: the accepted names, and that names are lowercase
    /// when only the case is wrong (profile fields, `--set`, `--strategy` and `strata study` alike).
    pub fn parse_or_explain(s: &str) -> Result<Strategy, String> {
        Strategy::parse(s).ok_or_else(|| {
            let all: Vec<_> = Strategy::ALL.iter().map(|s| s.name()).collect();
            format!("unknown strategy `{s}` (one of {}){}", all.join(", "), lowercase_hint(s))
        })
    }
}

/// For a name that is wrong only in case (or also in case): say that names are lowercase.
pub fn lowercase_hint(v: &str) -> &'static str {
    if v.bytes().any(|b| b.is_ascii_uppercase()) {
        "; names are lowercase, as in profile files"
    } else {
        ""
    }
}

impl std::fmt::Display for Strategy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The stratification of `n` samples: `[nx, ny]` with `nx` the largest divisor of `n` that is
/// `<= sqrt(n)` and `ny = n / nx`, so `nx * ny == n` exactly (a prime `n` gives `1 x n` strips).
/// `n == 0` is treated as 1. Cost: one division per candidate divisor below `sqrt(n)` (a single one for
/// squares; about `0.4 sqrt(n)` for `2^odd`; `sqrt(n)` for primes).
#[inline]
pub fn grid_shape(n: u32) -> [u32; 2] {
    let n = n.max(1);
    let mut nx = n.isqrt();
    while !n.is_multiple_of(nx) {
        nx -= 1;
    }
    [nx, n / nx]
}

/// The strata of a jittered set of `n` samples when [`grid_shape`]`(n)` is not square and `n` is not a
/// power of two, from 5 on (5, 7, 17, 31 = 1 x n; 18 = 3 x 6, 27 = 3 x 9, 33, 50, 65): `n` strata of equal area in `r = floor(sqrt(n))` rows, the
/// first `n % r` of `q + 1` cells and the rest of `q = n / r`, a row of `k` cells `k / n` high (each cell
/// `1 / k` wide: area `1 / n`, near square as `k` is within 2 of `sqrt(n)`). Every set takes every
/// stratum once, so each sample is uniform over the square in law (unbiased) and the set is
/// stratified along both axes, with no cell left out. `None` where the grid is square, and for powers of
/// two (2 x 1 grids: 8, 32, 128), which keep the grid's shift-only fast path.
///
/// (Before session 40 only strips more than 4 times longer than wide took rows. A second user trial
/// measured 3 x 9, 3 x 11 and 5 x 13 grids at 1.5x the MSE of the count below (27 against 25, 33
/// against 32, 65 against 64); in rows, `strata study scenes/quad_irradiance.toml --reference analytic
/// --integrals pixel --strategies jittered --seeds 16` gives 0.55x, 0.46x and 0.61x the grids' MSE, and
/// every other non-square count from 12 to 100 0.75-0.97x. Near-square counts (12 = 3 x 4, 20) take the
/// grid's cells transposed (3 rows of 4 for 12): the same strata shape, other images.)
///
/// (Before session 39 a set took `n` of the `m > n` strata of a covering grid: unbiased, but the cells
/// it left out added an error falling only as `1 / n`, which swamped the stratified part on smooth
/// integrands: 17 samples had 3x the MSE of 16, 67 had 5x that of 64, in a user trial's analytic study.)
#[inline]
pub fn jitter_rows(n: u32) -> Option<JitterRows> {
    let n = n.max(1);
    let [a, b] = grid_shape(n);
    (b > a && n > 4 && !n.is_power_of_two()).then(|| {
        let r = n.isqrt();
        JitterRows { n, q: n / r, rem: n % r }
    })
}

/// The equal-area rows of a jittered set ([`jitter_rows`]): `n` strata, the first `rem` rows of `q + 1`
/// cells, the others of `q`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct JitterRows {
    n: u32,
    q: u32,
    rem: u32,
}

impl JitterRows {
    /// Stratum `s < n`: its column, the cells `k` of its row and the cells `c0` of the rows below it
    /// (the row spans `[c0 / n, (c0 + k) / n)` in y, the cell `[col / k, (col + 1) / k)` in x).
    #[inline]
    pub fn cell(&self, s: u32) -> (u32, u32, u32) {
        let (q, big) = (self.q, self.rem * (self.q + 1));
        if s < big {
            (s % (q + 1), q + 1, s - s % (q + 1))
        } else {
            let t = s - big;
            (t % q, q, big + (t - t % q))
        }
    }

    /// A uniform point of stratum `s` from 64 random bits: exactly inside the cell (in 2^-24 fixed
    /// point, as [`jitter_in_cell`]).
    #[inline]
    fn jitter(&self, s: u32, h: u64) -> [f32; 2] {
        let (col, k, c0) = self.cell(s);
        [jitter_in_cell(col, k, (h >> 32) as u32), jitter_in_span(c0, k, self.n, h as u32)]
    }

    /// [`JitterRows::jitter`] for `s < n <= 2^24` in f64, bit for bit: every value is an integer held
    /// exactly, and each quotient is [`Divisor::quotient`]'s, exact (`d`, from [`JitterRows::divisors`]:
    /// the rows' two lengths and `n`); the span's `(b (k 2^24 + 1 - n)) >> 24`, which can pass 2^53, as
    /// `b k - ceil(b (n - 1) / 2^24)`, whose terms stay below 2^48.
    #[inline(always)]
    fn jitter_f64(&self, s: f64, h: u64, d: &[Divisor; 3]) -> [f32; 2] {
        const ONE: f64 = (1u64 << 24) as f64;
        let [short, long, n] = *d;
        let big = self.rem as f64 * long.d;
        let low = s < big;
        let (t, k) = if low { (s, long) } else { (s - big, short) };
        let row = k.quotient(t);
        let col = t - row * k.d;
        let c0 = if low { row * k.d } else { big + row * k.d };
        let x = jitter_in_cell_div(col, k, (h >> 32) as u32);
        let b = ((h as u32) >> 8) as f64;
        let t = (n.d - 1.0) + b * k.d - ((b * (n.d - 1.0) + (ONE - 1.0)) * (1.0 / ONE)).trunc();
        let y = n.quotient(c0 * ONE + t);
        [x, y.min(ONE - 1.0) as f32 * (1.0 / ONE as f32)]
    }

    /// The divisors of [`JitterRows::jitter_f64`]: rows of `q` and `q + 1` cells, and `n`.
    #[inline(always)]
    fn divisors(&self) -> [Divisor; 3] {
        [Divisor::new(self.q), Divisor::new(self.q + 1), Divisor::new(self.n)]
    }

    /// The centre of stratum `s` (for tests).
    pub fn centre(&self, s: u32) -> [f64; 2] {
        let (col, k, c0) = self.cell(s);
        [(col as f64 + 0.5) / k as f64, (c0 as f64 + 0.5 * k as f64) / self.n as f64]
    }

    /// The stratum a point of `[0, 1)^2` lies in (for tests).
    pub fn stratum_of(&self, p: [f32; 2]) -> u32 {
        let (x, y) = (p[0] as f64, p[1] as f64);
        (0..self.n)
            .find(|&s| {
                let (col, k, c0) = self.cell(s);
                let (n, k) = (self.n as f64, k as f64);
                (c0 as f64 / n..(c0 as f64 + k) / n).contains(&y) && (col as f64 / k..(col as f64 + 1.0) / k).contains(&x)
            })
            .expect("every point of the square lies in a stratum")
    }
}

/// [`jitter_in_cell`] over `k` cells from cell `c0` of `n`: a point of `[c0 / n, (c0 + k) / n)`, exactly
/// inside it (the same fixed point, with `t` uniform on `[n - 1, k 2^24 - 1]`).
#[inline]
fn jitter_in_span(c0: u32, k: u32, n: u32, bits: u32) -> f32 {
    const ONE: u128 = 1 << 24;
    let (n, k) = (n as u128, k as u128);
    let span = (k * ONE + 1).saturating_sub(n);
    let t = (n - 1) + (((bits >> 8) as u128 * span) >> 24);
    let q = (c0 as u128 * ONE + t) / n;
    q.min(ONE - 1) as f32 * (1.0 / ONE as f32)
}

/// The 32-bit permutation key of a sequence key (both halves folded in; `permute` mixes it again).
#[inline(always)]
fn perm_key(key: u64) -> u32 {
    (key >> 32) as u32 ^ (key as u32).rotate_left(16)
}

/// `(k + 0.5) / n`, the centre of cell `k` of `n` (correctly rounded; clamped below 1 for `n > 2^23`).
#[inline(always)]
fn cell_centre(k: u32, n: u32) -> f32 {
    ((k as f32 + 0.5) / n as f32).min(ONE_MINUS_EPSILON)
}

/// `(k + u) / n` with `u` from the high 24 bits of `bits`, computed in 2^-24 fixed point so that the
/// result lies *exactly* in `[k/n, (k+1)/n)`: float `(k + u) / n` rounds across the cell edge with
/// probability ~`k * 2^-25` (often, for large n). The result is `q / 2^24` with
/// `q = floor((k 2^24 + t) / n)` and `t` uniform on `[n - 1, 2^24 - 1]`, which gives
/// `ceil(k 2^24 / n) <= q <= floor(((k+1) 2^24 - 1) / n)`: every 2^-24 grid point of the cell, each
/// with probability equal to within `n / 2^24`. Exact for `n <= 2^24`; beyond that the cells are
/// thinner than the grid and `q` is only kept below 2^24.
#[inline(always)]
fn jitter_in_cell(k: u32, n: u32, bits: u32) -> f32 {
    const ONE: u64 = 1 << 24;
    let n = n as u64;
    let span = (ONE + 1).saturating_sub(n);
    let t = (n - 1) + (((bits >> 8) as u64 * span) >> 24);
    let a = k as u64 * ONE + t;
    // Sample counts are usually powers of two: a shift instead of a 64-bit division (same quotient).
    let q = if n.is_power_of_two() { a >> n.trailing_zeros() } else { a / n };
    q.min(ONE - 1) as f32 * (1.0 / ONE as f32)
}

/// An integer divisor `d >= 1` held in f64 with its reciprocal, for exact integer quotients by a
/// multiplication ([`Divisor::quotient`]), which vectorises where integer division does not and costs a
/// fraction of an f64 division.
#[derive(Clone, Copy, Debug)]
struct Divisor {
    d: f64,
    inv: f64,
}

impl Divisor {
    #[inline(always)]
    fn new(d: u32) -> Divisor {
        debug_assert!(d >= 1);
        Divisor { d: d as f64, inv: 1.0 / d as f64 }
    }

    /// `floor(a / d)` for an integer `0 <= a < 2^51` held in f64, exactly: `(a + 0.5) / d` lies at least
    /// `0.5 / d` from every integer (its fraction is `(r + 0.5) / d` for the remainder `r < d`), and
    /// `(a + 0.5) * fl(1 / d)`, rounded, is within a relative `2^-52` of it (two roundings of `2^-53`),
    /// so within `(a + 0.5) 2^-52 / d < 0.5 / d`: truncation gives the integer quotient. (`a + 0.5` is
    /// exact below 2^52.)
    #[inline(always)]
    fn quotient(&self, a: f64) -> f64 {
        ((a + 0.5) * self.inv).trunc()
    }
}

/// [`jitter_in_cell`] for `k < n <= 2^24`, in f64 (`k`, `n` integers held exactly): every value below is
/// an integer below 2^49, exact in f64, and the quotient `a / n` is [`Divisor::quotient`]'s, exact. The
/// result is `jitter_in_cell(k, n, bits)` bit for bit.
#[inline(always)]
fn jitter_in_cell_div(k: f64, n: Divisor, bits: u32) -> f32 {
    const ONE: f64 = (1u64 << 24) as f64;
    // (bits >> 8) (ONE + 1 - n) < 2^48: exact; >> 24 is a division by 2^24 and truncation.
    let t = (n.d - 1.0) + (((bits >> 8) as f64 * (ONE + 1.0 - n.d)) * (1.0 / ONE)).trunc();
    let q = n.quotient(k * ONE + t);
    q.min(ONE - 1.0) as f32 * (1.0 / ONE as f32)
}

/// [`jitter_in_cell`] for `k < n = 2^log2n <= 2^24`: the same quotient by shifts, branch-free, in 32-bit
/// lanes but for one 32 x 32 -> 64-bit product (`vpmuludq`, which AVX2 has: a 64-bit minimum and a
/// 64-bit integer to float conversion, which it lacks, made the 8-lane loop scalar there). Exact: `k 2^24`
/// is a multiple of `n`, so `(k 2^24 + t) >> log2n = (k << (24 - log2n)) + (t >> log2n)`; `t < 2^24`
/// and, for `k < n`, `q < 2^24` (`jitter_in_cell`'s clamp never acts), so `q` converts exactly.
#[inline(always)]
fn jitter_in_cell_pow2(k: u32, log2n: u32, bits: u32) -> f32 {
    const ONE: u32 = 1 << 24;
    debug_assert!(log2n <= 24 && k < 1 << log2n);
    let n = 1u32 << log2n;
    let t = (n - 1) + (((bits >> 8) as u64 * (ONE + 1 - n) as u64) >> 24) as u32;
    let q = (k << (24 - log2n)) + (t >> log2n);
    q as i32 as f32 * (1.0 / ONE as f32)
}

/// Sample `index` of an `n`-sample 2D estimate of one integral, for one `stream` and one `dim`.
/// Returns a point in `[0, 1)^2`. See the module doc for each strategy and for `index >= n`.
#[inline]
pub fn sample_2d(strategy: Strategy, seed: u64, stream: u64, dim: u32, index: u32, n: u32) -> [f32; 2] {
    if strategy == Strategy::Center {
        return [0.5, 0.5];
    }
    sample_2d_keyed(strategy, stream_key(seed, stream, dim), index, n)
}

/// [`sample_2d`] from a precomputed [`stream_key`]`(seed, stream, dim)`.
#[inline]
pub fn sample_2d_keyed(strategy: Strategy, key: u64, index: u32, n: u32) -> [f32; 2] {
    match strategy {
        Strategy::Center => [0.5, 0.5],
        Strategy::Random => random_2d_keyed(key, index),
        Strategy::Sobol => sobol_owen_2d(key, index),
        Strategy::Grid | Strategy::Jittered => {
            if let Some(rows) = jitter_rows(n).filter(|_| strategy == Strategy::Jittered) {
                return rows.jitter(permute(index, rows.n, perm_key(key)), random_bits(key, index));
            }
            let [nx, ny] = grid_shape(n);
            let s = permute(index, nx * ny, perm_key(key));
            let (sx, sy) = (s % nx, s / nx);
            if strategy == Strategy::Grid {
                [cell_centre(sx, nx), cell_centre(sy, ny)]
            } else {
                let h = random_bits(key, index);
                [jitter_in_cell(sx, nx, (h >> 32) as u32), jitter_in_cell(sy, ny, h as u32)]
            }
        }
    }
}

/// Sample `index` of an `n`-sample 1D estimate (time, roulette...): center -> 0.5, grid ->
/// `(k + 0.5) / n`, random -> [`random_f32`](super::random_f32), jittered -> `(k + u) / n`, sobol ->
/// Owen-scrambled van der Corput; `k = permute(index, n, ..)`. Returns a value in `[0, 1)`.
/// A 2D strategy for a set of `n` samples with the grid shape worked out once: the hot-loop form of
/// [`sample_2d_keyed`] (which recomputes the shape, an O(sqrt n) divisor search, on every call).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sampler2d {
    pub strategy: Strategy,
    pub n: u32,
    nx: u32,
    ny: u32,
    /// A jittered set's equal-area rows, for counts neither square nor a power of two ([`jitter_rows`]).
    rows: Option<JitterRows>,
}

impl Sampler2d {
    pub fn new(strategy: Strategy, n: u32) -> Sampler2d {
        let n = n.max(1);
        // (The grid's shape is a search over divisors, O(sqrt n): only for the strategies that use it.)
        let gridded = matches!(strategy, Strategy::Grid | Strategy::Jittered);
        let [nx, ny] = if gridded { grid_shape(n) } else { [1, n] };
        let rows = if strategy == Strategy::Jittered { jitter_rows(n) } else { None };
        Sampler2d { strategy, n, nx, ny, rows }
    }

    /// Sample `index` of the set keyed by `key` (see [`stream_key`]); equals `sample_2d_keyed(strategy, key, index, n)`.
    #[inline]
    pub fn sample(&self, key: u64, index: u32) -> [f32; 2] {
        self.sample_impl(key, index, true)
    }

    /// Sample `index` of a set that one estimate uses whole (e.g. the light samples of one shading point):
    /// no other dimension shares `index`, so the stratum needs no permutation and is `index` itself.
    /// Same strata and same distribution as [`Sampler2d::sample`], less hashing.
    #[inline]
    pub fn sample_unpermuted(&self, key: u64, index: u32) -> [f32; 2] {
        self.sample_impl(key, index, false)
    }

    /// Eight lanes of [`Sampler2d::sample`] (`permuted`) or [`Sampler2d::sample_unpermuted`]: lane `l`
    /// is sample `index[l]` of the set keyed by `keys[l]`. Bit-identical to the scalar calls. Jittered
    /// sets of a power-of-two size up to 2^24 (the usual counts) take a branch-free path whose lane loop
    /// the compiler vectorises; other strategies and sizes call the scalar sampler per lane.
    ///
    /// The power-of-two jittered path is inlined into the caller (its keys and indices, often splats or
    /// made lane by lane just before, then stay in registers instead of being reloaded as vectors from
    /// scalar stores); the other paths are one out-of-line call.
    #[inline(always)]
    pub fn sample_x8(&self, keys: &[u64; LANES], index: &[u32; LANES], permuted: bool) -> [f32x8; 2] {
        if self.jittered_pow2() {
            let (sh, mask) = (PermuteShape::new(self.n), self.n - 1);
            return self.jittered_pow2_x8(
                index,
                |l| keys[l],
                |l| if permuted { permute_pow2(index[l], &sh, perm_key(keys[l])) } else { index[l] & mask },
            );
        }
        self.sample_x8_general(keys, index, permuted)
    }

    /// [`Sampler2d::sample_x8`] as one out-of-line call: for loops that are long already (inlined
    /// there, its code made the shadow stage's loop slower).
    #[inline(never)]
    pub fn sample_x8_call(&self, keys: &[u64; LANES], index: &[u32; LANES], permuted: bool) -> [f32x8; 2] {
        self.sample_x8(keys, index, permuted)
    }

    /// [`Sampler2d::sample_x8`] of 8 samples of one set (every lane's key `key`: a pixel's samples):
    /// the same values, with what depends on the key alone (the permutation's constants) worked out
    /// once instead of per lane.
    #[inline(always)]
    pub fn sample_x8_one_key(&self, key: u64, index: &[u32; LANES], permuted: bool) -> [f32x8; 2] {
        if self.jittered_pow2() {
            let (perm, mask) = (PermutePow2::new(PermuteShape::new(self.n), perm_key(key)), self.n - 1);
            return self.jittered_pow2_x8(index, |_| key, |l| if permuted { perm.apply(index[l]) } else { index[l] & mask });
        }
        self.sample_x8_general(&[key; LANES], index, permuted)
    }

    /// Whether the set takes the branch-free 8-lane path: jittered, of a power-of-two size up to 2^24.
    #[inline(always)]
    fn jittered_pow2(&self) -> bool {
        self.strategy == Strategy::Jittered && self.n.is_power_of_two() && self.n <= 1 << 24
    }

    /// The 8-lane jittered power-of-two path: lane `l` jitters sample `index[l]` of the set keyed by
    /// `key(l)` in stratum `stratum(l)` (the permuted or plain index).
    #[inline(always)]
    fn jittered_pow2_x8(&self, index: &[u32; LANES], key: impl Fn(usize) -> u64, stratum: impl Fn(usize) -> u32) -> [f32x8; 2] {
        let mut u = [[0.0f32; LANES]; 2];
        let (lx, ly) = (self.nx.trailing_zeros(), self.ny.trailing_zeros());
        for l in 0..LANES {
            let s = stratum(l);
            let h = random_bits(key(l), index[l]);
            u[0][l] = jitter_in_cell_pow2(s & (self.nx - 1), lx, (h >> 32) as u32);
            u[1][l] = jitter_in_cell_pow2(s >> lx, ly, h as u32);
        }
        [f32x8::from(u[0]), f32x8::from(u[1])]
    }

    /// [`Sampler2d::sample_x8_one_key`] as one out-of-line call (see [`Sampler2d::sample_x8_call`]).
    #[inline(never)]
    pub fn sample_x8_one_key_call(&self, key: u64, index: &[u32; LANES], permuted: bool) -> [f32x8; 2] {
        self.sample_x8_one_key(key, index, permuted)
    }

    /// [`Sampler2d::sample_x8`] for every set but the power-of-two jittered ones.
    #[inline(never)]
    fn sample_x8_general(&self, keys: &[u64; LANES], index: &[u32; LANES], permuted: bool) -> [f32x8; 2] {
        if self.strategy == Strategy::Sobol {
            // (Points of the sequence, whatever the set's size: vector operations, no scalar path.)
            return super::sobol::sobol_owen_2d_x8(keys, index);
        }
        let mut u = [[0.0f32; LANES]; 2];
        if self.strategy == Strategy::Jittered && self.n <= 1 << 24 && index.iter().all(|&i| i < self.n) {
            // Other counts (48, 100, 1000 spp): the cycle-walking permutation in 8 lanes.
            let s = if permuted { permute_x8(index, &PermuteShape::new(self.n), &keys.map(perm_key)) } else { *index };
            return self.jitter_strata_x8(keys, index, &s);
        } else if self.strategy == Strategy::Grid && !permuted && index.iter().all(|&i| i == index[0]) {
            // An unpermuted grid sample depends on its index alone (no key): one for all lanes (the
            // light samples of a grid, sample j at every shading point of a chunk).
            let [x, y] = self.sample_impl(keys[0], index[0], false);
            return [f32x8::splat(x), f32x8::splat(y)];
        } else if self.strategy == Strategy::Grid && self.n <= 1 << 24 && index.iter().all(|&i| i < self.n) {
            // Grid samples (e.g. a 2x2 grid of pixel positions): the centres of the strata the jittered
            // path above finds, the row and column by the same f64 quotient, the centres per lane.
            let s = if permuted { permute_x8(index, &PermuteShape::new(self.n), &keys.map(perm_key)) } else { *index };
            let nx = Divisor::new(self.nx);
            for l in 0..LANES {
                let sl = s[l] as f64;
                let sy = nx.quotient(sl);
                let sx = sl - sy * nx.d;
                u[0][l] = cell_centre(sx as u32, self.nx);
                u[1][l] = cell_centre(sy as u32, self.ny);
            }
        } else {
            for l in 0..LANES {
                [u[0][l], u[1][l]] = self.sample_impl(keys[l], index[l], permuted);
            }
        }
        [f32x8::from(u[0]), f32x8::from(u[1])]
    }

    /// The jittered samples in strata `s` (`s[l] < n <= 2^24`) of samples `index` of the sets keyed by
    /// `keys`: the same strata and jitter as `sample_impl`, the integer divisions as f64 multiplications
    /// by the reciprocal (exact here, see [`Divisor::quotient`]), which vectorise where the integer ones
    /// do not.
    #[inline(always)]
    fn jitter_strata_x8(&self, keys: &[u64; LANES], index: &[u32; LANES], s: &[u32; LANES]) -> [f32x8; 2] {
        let mut u = [[0.0f32; LANES]; 2];
        if let Some(rows) = &self.rows {
            // Counts in rows (5, 17, 31): `JitterRows::jitter`, its quotients likewise in f64.
            let d = rows.divisors();
            for l in 0..LANES {
                let h = random_bits(keys[l], index[l]);
                [u[0][l], u[1][l]] = rows.jitter_f64(s[l] as f64, h, &d);
            }
            return [f32x8::from(u[0]), f32x8::from(u[1])];
        }
        let (nx, ny) = (Divisor::new(self.nx), Divisor::new(self.ny));
        for l in 0..LANES {
            let sl = s[l] as f64;
            let sy = nx.quotient(sl);
            let sx = sl - sy * nx.d;
            let h = random_bits(keys[l], index[l]);
            u[0][l] = jitter_in_cell_div(sx, nx, (h >> 32) as u32);
            u[1][l] = jitter_in_cell_div(sy, ny, h as u32);
        }
        [f32x8::from(u[0]), f32x8::from(u[1])]
    }

    /// Whether [`Sampler2d::sample_x8_run`] gains over one [`Sampler2d::sample_x8`] per vector: a
    /// jittered set of another size than a power of two (up to 2^24), whose permutation walks cycles.
    #[inline(always)]
    pub fn runs(&self) -> bool {
        self.strategy == Strategy::Jittered && !self.n.is_power_of_two() && self.n <= 1 << 24
    }

    /// [`Sampler2d::sample_x8`] of a run of index vectors under the same 8 keys: `out[m]` is
    /// `sample_x8(keys, &index, permuted)` with `index[l] = base[l] + m step`, bit for bit, for `m <
    /// count <= RUN_MAX` (a chunk's light samples `j..j + count`, step 1; a pixel's samples, step 8).
    /// Where the set's permutation walks cycles (a size other than a power of two), each lane walks its
    /// run's elements one after another ([`permute_runs`]) instead of every vector waiting for its
    /// slowest lane.
    #[inline(never)]
    pub fn sample_x8_run(
        &self,
        keys: &[u64; LANES],
        base: &[u32; LANES],
        step: u32,
        count: usize,
        permuted: bool,
        out: &mut [[f32x8; 2]; RUN_MAX],
    ) {
        assert!(count <= RUN_MAX);
        let index = |m: usize| -> [u32; LANES] { std::array::from_fn(|l| base[l].wrapping_add(m as u32 * step)) };
        let last = (count as u64).saturating_sub(1) * step as u64;
        if !(self.runs() && base.iter().all(|&b| b as u64 + last < self.n as u64)) {
            for (m, o) in out.iter_mut().enumerate().take(count) {
                *o = self.sample_x8(keys, &index(m), permuted);
            }
            return;
        }
        let mut s = [[0u32; LANES]; RUN_MAX];
        if permuted {
            self.strata_runs(keys, base, step, &[count as u32; LANES], &mut s);
        } else {
            for (m, s) in s.iter_mut().enumerate().take(count) {
                *s = index(m);
            }
        }
        for m in 0..count {
            out[m] = self.jitter_strata_x8(keys, &index(m), &s[m]);
        }
    }

    /// The strata `sample_x8` takes for runs of samples of 8 sets, lane `l`'s keyed by `keys[l]`: `out[m][l]`
    /// is the permuted stratum of index `base[l] + m step`, for `m < count[l] <= RUN_MAX` (rows past a
    /// lane's count left alone). For sets that [`Sampler2d::runs`], every index below `n`: 8 pixels' samples
    /// of a work unit at once, a lane per pixel. Then [`Sampler2d::sample_x8_in_strata`].
    pub fn strata_runs(
        &self,
        keys: &[u64; LANES],
        base: &[u32; LANES],
        step: u32,
        count: &[u32; LANES],
        out: &mut [[u32; LANES]; RUN_MAX],
    ) {
        debug_assert!(self.runs());
        permute_runs(base, step, count, &PermuteShape::new(self.n), &keys.map(perm_key), out);
    }

    /// `sample_x8(keys, index, true)` of a set that [`Sampler2d::runs`], given the strata the permutation
    /// puts `index` in (`s`, from [`Sampler2d::strata_runs`]): bit for bit the same.
    #[inline(never)]
    pub fn sample_x8_in_strata(&self, keys: &[u64; LANES], index: &[u32; LANES], s: &[u32; LANES]) -> [f32x8; 2] {
        debug_assert!(self.runs());
        self.jitter_strata_x8(keys, index, s)
    }

    #[inline(always)]
    fn sample_impl(&self, key: u64, index: u32, permuted: bool) -> [f32; 2] {
        match self.strategy {
            Strategy::Center => [0.5, 0.5],
            Strategy::Random => random_2d_keyed(key, index),
            Strategy::Sobol => sobol_owen_2d(key, index),
            Strategy::Grid | Strategy::Jittered => {
                let (nx, ny) = (self.nx, self.ny);
                let s = if permuted { permute(index, nx * ny, perm_key(key)) } else { index % (nx * ny) };
                if let Some(rows) = &self.rows {
                    return rows.jitter(s, random_bits(key, index));
                }
                let (sx, sy) = if nx.is_power_of_two() { (s & (nx - 1), s >> nx.trailing_zeros()) } else { (s % nx, s / nx) };
                if self.strategy == Strategy::Grid {
                    [cell_centre(sx, nx), cell_centre(sy, ny)]
                } else {
                    let h = random_bits(key, index);
                    [jitter_in_cell(sx, nx, (h >> 32) as u32), jitter_in_cell(sy, ny, h as u32)]
                }
            }
        }
    }
}

#[inline]
pub fn sample_1d(strategy: Strategy, seed: u64, stream: u64, dim: u32, index: u32, n: u32) -> f32 {
    if strategy == Strategy::Center {
        return 0.5;
    }
    sample_1d_keyed(strategy, stream_key(seed, stream, dim), index, n)
}

/// [`sample_1d`] from a precomputed [`stream_key`]`(seed, stream, dim)`.
#[inline]
pub fn sample_1d_keyed(strategy: Strategy, key: u64, index: u32, n: u32) -> f32 {
    match strategy {
        Strategy::Center => 0.5,
        Strategy::Random => random_f32_keyed(key, index),
        Strategy::Sobol => sobol_owen_1d(key, index),
        Strategy::Grid | Strategy::Jittered => {
            let n = n.max(1);
            let k = permute(index, n, perm_key(key));
            if strategy == Strategy::Grid {
                cell_centre(k, n)
            } else {
                jitter_in_cell(k, n, (random_bits(key, index) >> 32) as u32)
            }
        }
    }
}

/// Eight lanes of [`sample_1d_keyed`] (shutter times and wavelengths of camera rays): lane `l` is
/// sample `index[l]` of the set keyed by `keys[l]`, bit for bit. Jittered sets of a power-of-two size
/// up to 2^24 (the usual counts) take a branch-free loop the compiler vectorises, with the permutation's
/// key constants worked out once where every lane has the key `keys[0]` (`one`: a pixel's samples);
/// other strategies and sizes take the scalar per lane.
#[inline(always)]
pub fn sample_1d_keyed_x8(strategy: Strategy, keys: &[u64; LANES], index: &[u32; LANES], n: u32, one: bool) -> [f32; LANES] {
    let n = n.max(1);
    let mut u = [0.0f32; LANES];
    if strategy == Strategy::Jittered && n.is_power_of_two() && n <= 1 << 24 {
        let (sh, log2n) = (PermuteShape::new(n), n.trailing_zeros());
        let bits = |key: u64, i: u32| (random_bits(key, i) >> 32) as u32;
        if one {
            let perm = PermutePow2::new(sh, perm_key(keys[0]));
            for l in 0..LANES {
                u[l] = jitter_in_cell_pow2(perm.apply(index[l]), log2n, bits(keys[0], index[l]));
            }
        } else {
            for l in 0..LANES {
                u[l] = jitter_in_cell_pow2(permute_pow2(index[l], &sh, perm_key(keys[l])), log2n, bits(keys[l], index[l]));
            }
        }
        return u;
    }
    for l in 0..LANES {
        u[l] = sample_1d_keyed(strategy, if one { keys[0] } else { keys[l] }, index[l], n);
    }
    u
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`sample_1d_keyed_x8`] against [`sample_1d_keyed`] bit for bit: every strategy, counts powers of
    /// two and not (1 to 2^24 and past it), indices within the set and past it (wrapped), one key per
    /// lane and one for all.
    #[test]
    fn sample_1d_x8_equals_the_scalar() {
        let mut next = crate::sample::hash::test_uniforms(0x51d8);
        for strategy in Strategy::ALL {
            for n in [1u32, 2, 3, 7, 16, 64, 100, 1024, 1 << 24, (1 << 24) + 1, 1 << 25] {
                for round in 0..40 {
                    let keys: [u64; LANES] = std::array::from_fn(|_| ((next() * 4e9) as u64) << 32 | (next() * 4e9) as u64);
                    let index: [u32; LANES] = std::array::from_fn(|l| match round % 4 {
                        0 => l as u32 % n,
                        1 => (next() * n as f32) as u32,
                        2 => (next() * 4e9) as u32,
                        _ => n - 1 - (l as u32).min(n - 1),
                    });
                    for one in [false, true] {
                        let got = sample_1d_keyed_x8(strategy, &keys, &index, n, one);
                        for l in 0..LANES {
                            let want = sample_1d_keyed(strategy, if one { keys[0] } else { keys[l] }, index[l], n);
                            assert_eq!(got[l].to_bits(), want.to_bits(), "{strategy:?} n={n} lane {l} index {} one {one}", index[l]);
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn sampler2d_matches_sample_2d_and_unpermuted_keeps_the_strata() {
        for strategy in Strategy::ALL {
            for n in [1u32, 2, 7, 9, 12, 64, 100] {
                let s = Sampler2d::new(strategy, n);
                let key = 0x1234_5678_9abc_def0u64 ^ n as u64;
                let mut cells = vec![0u32; n as usize];
                for i in 0..n {
                    assert_eq!(s.sample(key, i), sample_2d_keyed(strategy, key, i, n));
                    if matches!(strategy, Strategy::Grid | Strategy::Jittered) {
                        let u = s.sample_unpermuted(key, i);
                        let cell = match jitter_rows(n).filter(|_| strategy == Strategy::Jittered) {
                            // (Unpermuted: sample i in stratum i.)
                            Some(rows) => {
                                assert_eq!(rows.stratum_of(u), i, "{strategy:?} n={n}");
                                i
                            }
                            None => {
                                let [nx, ny] = grid_shape(n);
                                (u[1] * ny as f32) as u32 * nx + (u[0] * nx as f32) as u32
                            }
                        };
                        cells[cell as usize] += 1;
                    }
                }
                // n distinct strata: all of them (a jittered 7 in rows of 4 and 3 cells).
                if matches!(strategy, Strategy::Grid | Strategy::Jittered) {
                    assert!(cells.iter().all(|&c| c <= 1) && cells.iter().sum::<u32>() == n, "{strategy:?} n={n}: {cells:?}");
                }
            }
        }
    }

    /// A run of index vectors against one `sample_x8` per vector, bit for bit: every strategy, sizes with
    /// long and short walks, runs of 1 to `RUN_MAX` vectors, steps 1 and 8, permuted or not, and indices
    /// past the set (the per-vector fallback).
    #[test]
    fn sample_x8_run_matches_sample_x8() {
        use crate::sample::hash::{mix32, mix64};
        for strategy in Strategy::ALL {
            for n in [1u32, 3, 5, 16, 17, 31, 48, 67, 100, 272, 1000, 4095, 1_000_003, (1 << 24) - 1] {
                let s = Sampler2d::new(strategy, n);
                for count in 1..=RUN_MAX {
                    for round in 0..6u64 {
                        let keys = std::array::from_fn(|l| mix64(round * 8 + l as u64 + n as u64 * 31));
                        let step = if round % 2 == 0 { 1 } else { 8 };
                        let span = (count as u32 - 1) * step;
                        // The last round's runs pass the end of the set.
                        let base = std::array::from_fn(|l| {
                            let b = mix32((round * 64 + count as u64) as u32 + l as u32);
                            if round == 5 || span >= n {
                                b % (n + 8)
                            } else {
                                b % (n - span)
                            }
                        });
                        for permuted in [true, false] {
                            let mut out = [[f32x8::ZERO; 2]; RUN_MAX];
                            s.sample_x8_run(&keys, &base, step, count, permuted, &mut out);
                            for (m, got) in out.iter().enumerate().take(count) {
                                let index = std::array::from_fn(|l| base[l] + m as u32 * step);
                                let want = s.sample_x8(&keys, &index, permuted);
                                for d in 0..2 {
                                    assert_eq!(
                                        got[d].to_array().map(f32::to_bits),
                                        want[d].to_array().map(f32::to_bits),
                                        "{strategy:?} n={n} count={count} step={step} m={m} permuted={permuted}"
                                    );
                                }
                            }
                        }
                    }
                }
            }
        }
    }

    /// The 8-lane sampler against the scalar one, bit for bit, for every strategy, power-of-two and
    /// other sizes, permuted or not, indices inside and past the set, distinct or shared by the lanes.
    #[test]
    fn sample_x8_matches_scalar() {
        for strategy in Strategy::ALL {
            for n in [
                1u32,
                2,
                3,
                4,
                5,
                6,
                7,
                8,
                12,
                16,
                17,
                31,
                48,
                64,
                67,
                100,
                256,
                1000,
                4095,
                1_000_003,
                1 << 20,
                (1 << 24) - 3,
                (1 << 24) - 1,
                1 << 24,
                (1 << 24) + 1,
                1 << 25,
            ] {
                let s = Sampler2d::new(strategy, n);
                for round in 0..40u64 {
                    let keys = std::array::from_fn(|l| crate::sample::hash::mix64(round * 8 + l as u64 + n as u64));
                    // Every fifth round all lanes share one index (as a chunk's light samples do).
                    let lane = |l: u32| if round % 5 == 3 { 0 } else { l };
                    let index = std::array::from_fn(|l| {
                        (round as u32 * 8 + lane(l as u32)).wrapping_mul(if round % 5 == 4 { 0x9e37_79b9 } else { 1 })
                    });
                    for permuted in [true, false] {
                        let got = s.sample_x8(&keys, &index, permuted);
                        // The one-key form, with the first lane's key in every lane.
                        let one = s.sample_x8_one_key(keys[0], &index, permuted);
                        for l in 0..LANES {
                            let want = if permuted { s.sample(keys[l], index[l]) } else { s.sample_unpermuted(keys[l], index[l]) };
                            let g = [got[0].to_array()[l], got[1].to_array()[l]];
                            assert_eq!(g.map(f32::to_bits), want.map(f32::to_bits), "{strategy:?} n={n} lane {l} permuted={permuted}");
                            let want = if permuted { s.sample(keys[0], index[l]) } else { s.sample_unpermuted(keys[0], index[l]) };
                            let g = [one[0].to_array()[l], one[1].to_array()[l]];
                            assert_eq!(
                                g.map(f32::to_bits),
                                want.map(f32::to_bits),
                                "{strategy:?} n={n} lane {l} one key, permuted={permuted}"
                            );
                        }
                    }
                }
            }
        }
    }

    /// The 32-bit shifts of `jitter_in_cell_pow2` give `jitter_in_cell`'s value bit for bit, for every
    /// power of two up to 2^24: the first, second, middle and last two cells, the bits at both ends of
    /// the 24 used (and the low 8, unused), and random bits.
    #[test]
    fn jitter_in_cell_pow2_equals_integer_division() {
        let mut next = crate::sample::hash::test_uniforms(0x9042);
        for log2n in 0..=24u32 {
            let n = 1u32 << log2n;
            let mut bits: Vec<u32> = vec![0, 1, 255, 256, 0x8000_0000, u32::MAX, u32::MAX - 255];
            bits.extend((0..200).map(|_| (next() * 16_777_216.0) as u32).map(|b| b << 8 | (b & 0xff)));
            for k in [0, 1, n / 2, n.saturating_sub(2), n - 1].into_iter().filter(|&k| k < n) {
                for &b in &bits {
                    assert_eq!(jitter_in_cell_pow2(k, log2n, b).to_bits(), jitter_in_cell(k, n, b).to_bits(), "n={n} k={k} bits={b:#x}");
                }
            }
        }
    }

    /// The f64 quotient of `jitter_in_cell_div` equals the u64 one of `jitter_in_cell`: every cell
    /// edge case (first, middle, last cell), bits at both ends and where `k 2^24 + t` is a multiple of
    /// `n` (the quotient then exact), for counts up to 2^24 that are not powers of two.
    #[test]
    fn jitter_in_cell_div_equals_integer_division() {
        let mut next = crate::sample::hash::test_uniforms(0xd1f);
        for n in [3u32, 5, 6, 7, 48, 49, 98, 100, 1000, 4095, 65_537, 1_000_003, (1 << 24) - 3, (1 << 24) - 1] {
            let span = (1u64 << 24) + 1 - n as u64;
            for k in [0, 1, n / 2, n - 2, n - 1] {
                let mut bits: Vec<u32> = vec![0, 255, 256, u32::MAX, u32::MAX - 255];
                bits.extend((0..300).map(|_| (next() * 16_777_216.0) as u32).map(|b| b << 8));
                // Bits whose t makes k 2^24 + t a multiple of n (those reachable with 24 bits).
                let a0 = k as u64 * (1 << 24) + (n as u64 - 1);
                let first = a0.div_ceil(n as u64) * n as u64 - a0;
                for target in (0..400).map(|j| first + j * n as u64) {
                    let b = (target << 24).div_ceil(span);
                    if b < 1 << 24 {
                        assert_eq!(k as u64 * (1 << 24) + (n as u64 - 1) + ((b * span) >> 24), a0 + target);
                        bits.push((b as u32) << 8);
                    }
                }
                for b in bits {
                    assert_eq!(
                        jitter_in_cell_div(k as f64, Divisor::new(n), b).to_bits(),
                        jitter_in_cell(k, n, b).to_bits(),
                        "n={n} k={k} bits={b}"
                    );
                }
            }
        }
    }

    /// [`Divisor::quotient`] is the integer quotient: every divisor's multiples and their neighbours, for
    /// divisors up to 2^24 - 1 (the column counts of the grids of up to 2^24 samples) and beyond, and
    /// dividends up to the 2^51 its proof allows (the jitter's reach 2^49), against u64 division.
    #[test]
    fn divisor_quotient_is_exact() {
        let mut next = crate::sample::hash::test_uniforms(0x9d1);
        let mut wide = || {
            (((next() as f64 * 16_777_216.0) as u64) << 27)
                ^ ((next() as f64 * 16_777_216.0) as u64)
                ^ ((next() as f64 * 16_777_216.0) as u64) << 3
        };
        let divisors =
            [1u64, 2, 3, 7, 48, 49, 98, 103, 161, 1000, 4095, 4097, 65_535, 1_000_003, (1 << 23) + 1, (1 << 24) - 1, (1 << 31) - 1];
        for d in divisors {
            let div = Divisor::new(d as u32);
            let mut checked = 0;
            for top in [1u64 << 24, 1 << 49, 1 << 51] {
                let step = (top / d / 200).max(1);
                for q in (0..=top / d).step_by(step as usize).chain([(top / d).saturating_sub(1), top / d]) {
                    for a in [q * d, (q * d).wrapping_sub(1), q * d + 1, q * d + d / 2, q * d + d - 1] {
                        if a < top {
                            assert_eq!(div.quotient(a as f64), (a / d) as f64, "{a} / {d}");
                            checked += 1;
                        }
                    }
                }
            }
            for _ in 0..500 {
                let a = wide() & ((1 << 51) - 1);
                assert_eq!(div.quotient(a as f64), (a / d) as f64, "{a} / {d}");
            }
            assert!(checked >= 12, "{d}");
        }
    }

    /// Counts that are neither squares nor powers of two take `n` equal-area strata in `floor(sqrt(n))` rows: each row's cells
    /// are as many as `n / r` or one more, the rows stack to exactly the square, every stratum's area is
    /// `1 / n` and near square (its sides within a factor 2.5 of each other: 7 has 4 cells of 1/4 x 4/7),
    /// and every point of the square lies in exactly one.
    #[test]
    fn jitter_rows_are_equal_area_strata() {
        for n in [0, 1, 2, 3, 4, 8, 9, 16, 32, 64, 2048] {
            assert_eq!(jitter_rows(n), None, "n = {n}: a square grid, a power of two or 3 (one row)");
        }
        for (n, rows) in [
            (5, vec![3, 2]),
            (6, vec![3, 3]),
            (7, vec![4, 3]),
            (17, vec![5, 4, 4, 4]),
            (18, vec![5, 5, 4, 4]),
            (22, vec![6, 6, 5, 5]),
            (27, vec![6, 6, 5, 5, 5]),
            (31, vec![7, 6, 6, 6, 6]),
        ] {
            let r = jitter_rows(n).expect("strips");
            let mut got = Vec::new();
            let mut s = 0;
            while s < n {
                let (col, k, c0) = r.cell(s);
                assert_eq!((col, c0), (0, s), "n = {n}: a row starts at stratum {s}");
                got.push(k);
                s += k;
            }
            assert_eq!(got, rows, "n = {n}");
        }
        for n in (1..3000u32).chain([4099, 65_537, 1 << 20 | 1, (1 << 24) - 3]) {
            let Some(r) = jitter_rows(n) else { continue };
            let (mut below, mut height) = (0u32, 0.0f64);
            for s in 0..n {
                let (col, k, c0) = r.cell(s);
                assert!(col < k && c0 == below, "n = {n} s = {s}");
                let (w, h) = (1.0 / k as f64, k as f64 / n as f64);
                assert!((w * h * n as f64 - 1.0).abs() < 1e-12 && w < 2.5 * h && h < 2.5 * w, "n = {n} s = {s}: {w} x {h}");
                if col == k - 1 {
                    below += k;
                    height += h;
                }
            }
            assert!(below == n && (height - 1.0).abs() < 1e-9, "n = {n}");
            if n < 200 {
                for s in 0..n {
                    let c = r.centre(s);
                    assert_eq!(r.stratum_of([c[0] as f32, c[1] as f32]), s, "n = {n}");
                }
            }
        }
    }

    /// The row jitter stays in its span of rows exactly (as `jitter_in_cell` in its cell), at both
    /// extremes of the random bits, and reaches both ends of it.
    #[test]
    fn jitter_in_span_stays_in_its_rows_exactly() {
        for n in [5u32, 7, 17, 31, 4099, (1 << 20) + 1, (1 << 24) - 3] {
            let r = jitter_rows(n).unwrap();
            let strata: Vec<u32> = if n < 5000 { (0..n).collect() } else { vec![0, 1, n / 2, n - 2, n - 1] };
            for s in strata {
                let (_, k, c0) = r.cell(s);
                for bits in [0u32, 255, 256, 1 << 31, u32::MAX - 256, u32::MAX] {
                    let y = jitter_in_span(c0, k, n, bits);
                    let q = (y * 16_777_216.0) as u64;
                    assert_eq!(q as f32 / 16_777_216.0, y);
                    let (lo, hi) = (c0 as u64 * (1 << 24), (c0 + k) as u64 * (1 << 24));
                    assert!(q * n as u64 >= lo && q * (n as u64) < hi, "n={n} s={s} bits={bits:#x}");
                }
                if n < 100 {
                    let first = (jitter_in_span(c0, k, n, 0) * 16_777_216.0) as u64;
                    let last = (jitter_in_span(c0, k, n, u32::MAX) * 16_777_216.0) as u64;
                    assert_eq!((first, last), ((c0 as u64 * (1 << 24)).div_ceil(n as u64), (((c0 + k) as u64) * (1 << 24) - 1) / n as u64));
                }
            }
        }
        // The f64 form of the 8-lane path equals the integer one, bit for bit, at the bits' extremes.
        for n in [5u32, 7, 17, 31, 67, 4099, 1_000_003, (1 << 24) - 3] {
            let r = jitter_rows(n).unwrap();
            let strata: Vec<u32> = if n < 5000 { (0..n).collect() } else { vec![0, 1, n / 3, n / 2, n - 2, n - 1] };
            for s in strata {
                for h in [0u64, 255, 256, u64::MAX, u64::MAX - 255, 0x8000_0000_8000_0000, 0x1234_5678_9abc_def0] {
                    assert_eq!(
                        r.jitter_f64(s as f64, h, &r.divisors()).map(f32::to_bits),
                        r.jitter(s, h).map(f32::to_bits),
                        "n={n} s={s} h={h:#x}"
                    );
                }
            }
        }
        // A span of one cell is `jitter_in_cell`.
        for (k, n, bits) in [(0, 7, 12345u32), (3, 7, u32::MAX), (16, 17, 1 << 31)] {
            assert_eq!(jitter_in_span(k, 1, n, bits), jitter_in_cell(k, n, bits));
        }
    }

    #[test]
    fn grid_shape_is_most_square_factorisation() {
        assert_eq!(grid_shape(0), [1, 1]);
        assert_eq!(grid_shape(1), [1, 1]);
        assert_eq!(grid_shape(2), [1, 2]);
        assert_eq!(grid_shape(7), [1, 7]);
        assert_eq!(grid_shape(8), [2, 4]);
        assert_eq!(grid_shape(12), [3, 4]);
        assert_eq!(grid_shape(36), [6, 6]);
        assert_eq!(grid_shape(2048), [32, 64]);
        assert_eq!(grid_shape(u32::MAX), [65535, 65537]);
        // Brute-force reference for every n up to 2000.
        for n in 1..2000u32 {
            let best = (1..=n).filter(|d| n % d == 0 && d * d <= n).max().unwrap();
            assert_eq!(grid_shape(n), [best, n / best], "n = {n}");
        }
    }

    /// The fixed-point jitter stays in its cell exactly, in integer arithmetic, at both extremes of
    /// the random bits, for every cell of several n (including n beyond the 24-bit grid).
    #[test]
    fn jitter_stays_in_cell_exactly() {
        for n in [1u32, 2, 3, 7, 100, 4096, 4099, 1 << 20, (1 << 24) - 3, 1 << 24] {
            let ks: Vec<u32> = if n <= 5000 { (0..n).collect() } else { vec![0, 1, 2, n / 3, n / 2, n - 2, n - 1] };
            for k in ks {
                for bits in [0u32, 255, 256, 1 << 31, u32::MAX - 256, u32::MAX] {
                    let x = jitter_in_cell(k, n, bits);
                    let q = (x * 16_777_216.0) as u64;
                    assert_eq!(q as f32 / 16_777_216.0, x);
                    let (lo, hi) = (k as u64 * (1 << 24), (k as u64 + 1) * (1 << 24));
                    assert!(q * n as u64 >= lo && q * (n as u64) < hi, "n={n} k={k} bits={bits:#x}");
                }
            }
        }
        // Beyond 2^24 cells: still in [0, 1).
        for n in [(1u32 << 24) + 1, u32::MAX] {
            for k in [0, n / 2, n - 1] {
                let x = jitter_in_cell(k, n, u32::MAX);
                assert!((0.0..1.0).contains(&x));
            }
        }
        // The whole cell is reachable: extremes of the bits hit its first and last grid points.
        let (n, k) = (3u32, 1u32);
        let first = (jitter_in_cell(k, n, 0) * 16_777_216.0) as u64;
        let last = (jitter_in_cell(k, n, u32::MAX) * 16_777_216.0) as u64;
        assert_eq!(first, (1u64 << 24).div_ceil(3));
        assert_eq!(last, ((2u64 << 24) - 1) / 3);
    }

    #[test]
    fn names_round_trip() {
        for s in Strategy::ALL {
            assert_eq!(Strategy::parse(s.name()), Some(s));
            assert_eq!(Strategy::parse(&s.name().to_uppercase()), None, "names are lowercase");
            assert_eq!(s.to_string(), s.name());
        }
        assert_eq!(Strategy::parse("centre"), Some(Strategy::Center));
        assert_eq!(Strategy::parse("halton"), None);
        assert_eq!(Strategy::parse(""), None);
        // Profile files take the same names (serde), `centre` included, and write `center`.
        #[derive(serde::Deserialize, serde::Serialize)]
        struct W {
            s: Strategy,
        }
        for (text, want) in [("s = \"centre\"", Strategy::Center), ("s = \"center\"", Strategy::Center), ("s = \"sobol\"", Strategy::Sobol)]
        {
            let w: W = toml::from_str(text).unwrap();
            assert_eq!(w.s, want, "{text}");
        }
        assert!(toml::from_str::<W>("s = \"halton\"").is_err());
        assert_eq!(toml::to_string(&W { s: Strategy::Center }).unwrap().trim(), "s = \"center\"");
    }

    #[test]
    fn keyed_equals_unkeyed() {
        for s in Strategy::ALL {
            for i in 0..20 {
                let key = stream_key(3, 77, 5);
                assert_eq!(sample_2d(s, 3, 77, 5, i, 9), sample_2d_keyed(s, key, i, 9));
                assert_eq!(sample_1d(s, 3, 77, 5, i, 9), sample_1d_keyed(s, key, i, 9));
            }
        }
    }
}
