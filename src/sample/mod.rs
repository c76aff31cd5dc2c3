//! Deterministic sampling for distribution ray tracing (Cook, Porter & Carpenter 1984, "Distributed Ray
//! Tracing"; Cook 1986, "Stochastic Sampling in Computer Graphics").
//!
//! # Stateless
//! Every random number is a pure function of `(seed, stream, dim, index)`: there is no generator state,
//! so an image is bit-identical for any thread count, tile order or sample range (rendering samples
//! `0..8` then `8..16` gives the same pixels as `0..16`).
//!
//! - `seed`: the render's seed (changes every sample of the image).
//! - `stream`: one sequence of estimates, typically the pixel index, or
//!   `hash_combine(hash_combine(pixel, sample), bounce)` for integrals that are sampled once per path.
//! - `dim`: which integral (pixel area, lens, time, light, glossy lobe, roulette...): different `dim`s of
//!   one stream are decorrelated (their strata and Sobol points are shuffled independently).
//! - `index` in `0..n`: which of the `n` samples of that integral.
//!
//! # Strategies ([`Strategy`])
//! - `center`: always `(0.5, 0.5)` (1D: 0.5), whatever `n`.
//! - `grid`: the centres of an `nx x ny` grid of sub-squares (1D: `(k + 0.5) / n`); no randomness in the
//!   *set* of points, identical for every stream: a midpoint quadrature rule.
//! - `random`: independent uniform points (the hash of the inputs).
//! - `jittered`: one uniform point in each of the `nx x ny` strata (in each of `n` equal-area strata in
//!   rows for counts without near-square factors, below; 1D: `(k + u) / n`).
//! - `sobol`: Owen-scrambled Sobol (0,2)-sequence by hash-based nested uniform scrambling (Burley 2020),
//!   scrambled per `(seed, stream, dim)`, with the index also shuffled per `(seed, stream, dim)`. The
//!   first `2^m` points of any sequence are a (0,m,2)-net; best with `n` a power of two, but any `n`
//!   works (it uses the first `n` points). `n` is not used.
//!
//! Non-square `n` (grid, jittered): `nx` is the largest divisor of `n` that is `<= sqrt(n)` and
//! `ny = n / nx` ([`grid_shape`]), so there are always exactly `n` strata (a prime `n` gives `1 x n`
//! strips, `n = 8` gives `2 x 4`). Jittered sets of a count that is neither a square nor a power of two
//! (from 5 on) take `n` equal-area strata in `r = floor(sqrt(n))` rows instead ([`jitter_rows`]:
//! a row of `k` cells is `k / n` high, each cell `1 / k` wide; 7 -> rows of 4 and 3, 17 -> 5, 4, 4, 4),
//! each once. The stratum of sample `index` is `permute(index, n, key)`
//! ([`permute`], after Kensler 2013), with `key` from `(seed, stream, dim)`: the pixel-area, lens and
//! time samples of one pixel sample land in unrelated strata. Stratum `s` is column `s % nx`, row
//! `s / nx` (in rows, the `s`-th cell counted row by row).
//!
//! # Conventions
//! - Every sample is in `[0, 1)`, never NaN, never 1.0. Random, jittered and sobol coordinates are
//!   multiples of 2^-24; grid coordinates are the correctly rounded centres `(k + 0.5) / n`.
//! - Jittered points lie *exactly* in their stratum `[k/n, (k+1)/n)` (computed in fixed point; float
//!   `(k + u) / n` would round onto the next stratum's edge), for up to 2^24 strata per axis.
//! - `n == 0` is treated as 1. `index >= n` never panics: grid and jittered wrap the stratum
//!   (`index % m`, the jitter still uses the full index, so it is a fresh point in a repeated stratum);
//!   random and sobol simply continue their sequence.
//! - The `_keyed` variants take a precomputed [`stream_key`]`(seed, stream, dim)` (saves four 64-bit
//!   mixes per call when many samples of one sequence are drawn).
//! - Hashing: SplitMix64's output function (Stafford Mix13), see [`hash`].
//!
//! # Warps
//! [`sample_filter`] importance-samples the pixel filter (weight 1 per sample), and
//! [`sample_disk_concentric`] maps the square to the lens disk (Shirley & Chiu 1997). Both are
//! measure-preserving, so stratification of the input carries over.

pub mod filter;
pub mod hash;
pub mod sobol;
pub mod strategy;
pub mod warp;

pub use filter::{sample_filter, sample_filter_pdf, sample_filter_x8, Filter};
pub use hash::{hash_combine, hash_u32, mix64, permute, random_2d_keyed, random_f32, random_f32_keyed, stream_key, ONE_MINUS_EPSILON};
pub use sobol::{sobol_owen_1d, sobol_owen_2d};
pub use strategy::{
    grid_shape, jitter_rows, sample_1d, sample_1d_keyed, sample_1d_keyed_x8, sample_2d, sample_2d_keyed, JitterRows, Sampler2d, Strategy,
};
pub use warp::{sample_disk_concentric, sample_disk_concentric_pdf, sample_disk_concentric_x8};
