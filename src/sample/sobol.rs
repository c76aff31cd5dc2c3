//! Owen-scrambled Sobol points by hash-based nested uniform scrambling (Burley 2020, "Practical Hash-based
//! Owen Scrambling", JCGT 9(4)).
//!
//! The first two Sobol dimensions form a (0,2)-sequence: dimension 0 is the van der Corput sequence (bit
//! reversal) and dimension 1 uses the upper-triangular Pascal matrix mod 2 as generator matrix (direction
//! numbers `v_{k+1} = v_k ^ (v_k >> 1)`). Every aligned block of `2^m` consecutive points is a
//! (0,m,2)-net.
//!
//! Owen scrambling flips digit `j` of a coordinate by a random function of digits `0..j` (most
//! significant first). Burley's trick: reverse the bits, so that the "higher digits" become the *lower*
//! bits, and apply a hash in which output bit `j` is input bit `j` xor a function of input bits `< j`
//! only. Additions and multiplications have exactly that carry structure (Laine & Karras 2011). Our hash
//! is our own sequence of such steps, seeded per `(seed, stream, dim)`.
//!
//! The index is shuffled by the same scramble applied to the index itself (in reversed order, so that bit
//! `b` of the index is flipped by a function of the bits above it): the first `2^m` shuffled indices form
//! one aligned block of `2^m`, hence still a (0,m,2)-net, but different `dim`s of one stream use different
//! blocks in different orders, which decorrelates the 2D pairs (Burley's "padding" by shuffling).

use super::hash::{mix64, unit_f32};
use crate::simd::{f32x8, i32x8, u32x8};

/// Generator of Sobol dimension 1: row `k` is the direction number for index bit `k`.
const SOBOL_DIM1: [u32; 32] = sobol_dim1_directions();

const fn sobol_dim1_directions() -> [u32; 32] {
    let mut v = [0u32; 32];
    let mut d = 1u32 << 31;
    let mut k = 0;
    while k < 32 {
        v[k] = d;
        d ^= d >> 1;
        k += 1;
    }
    v
}

/// The generator matrix applied a byte at a time: `SOBOL_DIM1_BYTES[b][v]` is the xor of the direction
/// numbers of the set bits of byte value `v` at byte position `b` (4 KiB, built at compile time). Four
/// lookups replace a 32-step bit loop; shuffled indices have random high bits, so the loop would always
/// run all 32 steps.
static SOBOL_DIM1_BYTES: [[u32; 256]; 4] = sobol_dim1_byte_tables();

const fn sobol_dim1_byte_tables() -> [[u32; 256]; 4] {
    let mut t = [[0u32; 256]; 4];
    let mut b = 0;
    while b < 4 {
        let mut v = 0;
        while v < 256 {
            let mut x = 0u32;
            let mut k = 0;
            while k < 8 {
                if v & (1 << k) != 0 {
                    x ^= SOBOL_DIM1[8 * b + k];
                }
                k += 1;
            }
            t[b][v] = x;
            v += 1;
        }
        b += 1;
    }
    t
}

/// The unscrambled 2D Sobol point `index` as 32-bit fixed-point fractions.
#[inline]
pub fn sobol_2d_u32(index: u32) -> [u32; 2] {
    let [b0, b1, b2, b3] = index.to_le_bytes();
    let y = SOBOL_DIM1_BYTES[0][b0 as usize]
        ^ SOBOL_DIM1_BYTES[1][b1 as usize]
        ^ SOBOL_DIM1_BYTES[2][b2 as usize]
        ^ SOBOL_DIM1_BYTES[3][b3 as usize];
    [index.reverse_bits(), y]
}

/// Bit-by-bit reference of [`sobol_2d_u32`]'s second coordinate (the test's ground truth).
#[cfg(test)]
fn sobol_dim1_bitwise(index: u32) -> u32 {
    (0..32).filter(|k| index >> k & 1 == 1).fold(0, |y, k| y ^ SOBOL_DIM1[k])
}

/// Nested-uniform-scramble hash in reversed-bit order: output bit `j` is input bit `j` xor a
/// pseudo-random function of `seed` and input bits `< j`. Every step is either `x + c`, `x * odd`, or
/// `x ^ (x * even)` with an even constant `= 2 mod 4`, each of which has that structure and is a
/// bijection of `u32`.
#[inline(always)]
pub fn owen_hash_reversed(x: u32, seed: u32) -> u32 {
    let mut x = x;
    x ^= x.wrapping_mul(0x9e37_79ba);
    x = x.wrapping_add(seed);
    x = x.wrapping_mul((seed >> 15) | 1);
    x ^= x.wrapping_mul(0x2545_f492);
    x = x.wrapping_add(seed.rotate_left(11) ^ 0x68e3_1da4);
    x ^= x.wrapping_mul(0x5851_f42e);
    x ^= x.wrapping_mul(0x7feb_352a);
    x
}

/// Owen-scramble a 32-bit fixed-point fraction: digit `j` (from the most significant) is flipped by a
/// function of `seed` and the digits before it.
#[inline(always)]
pub fn owen_scramble(x: u32, seed: u32) -> u32 {
    owen_hash_reversed(x.reverse_bits(), seed).reverse_bits()
}

/// The three 32-bit seeds (index shuffle, x scramble, y scramble) of one sequence key.
#[inline(always)]
fn seeds(key: u64) -> [u32; 3] {
    let k2 = mix64(key ^ 0x5bd1_e995_c6a4_a793);
    [key as u32, (key >> 32) as u32, k2 as u32]
}

/// Point `index` of the Owen-scrambled, index-shuffled 2D Sobol sequence `key`, in `[0, 1)^2`.
/// Any `index` is valid (the sequence simply continues past `n`).
#[inline]
pub fn sobol_owen_2d(key: u64, index: u32) -> [f32; 2] {
    let [s_index, s_x, s_y] = seeds(key);
    let shuffled = owen_scramble(index, s_index);
    let [x, y] = sobol_2d_u32(shuffled);
    [unit_f32(owen_scramble(x, s_x)), unit_f32(owen_scramble(y, s_y))]
}

/// Point `index` of the Owen-scrambled, index-shuffled van der Corput sequence `key`, in `[0, 1)`.
#[inline]
pub fn sobol_owen_1d(key: u64, index: u32) -> f32 {
    let [s_index, s_x, _] = seeds(key);
    let shuffled = owen_scramble(index, s_index);
    // owen_scramble(reverse(i)) = reverse(hash(i)): skip the double reversal.
    unit_f32(owen_hash_reversed(shuffled, s_x).reverse_bits())
}

/// [`u32::reverse_bits`] in 8 lanes: five swap stages of halves, quarters, ... bits.
#[inline(always)]
fn reverse_bits_x8(v: u32x8) -> u32x8 {
    let swap = |v: u32x8, s: u32, m: u32| ((v >> s) & u32x8::splat(m)) | ((v & u32x8::splat(m)) << s);
    let v = swap(v, 1, 0x5555_5555);
    let v = swap(v, 2, 0x3333_3333);
    let v = swap(v, 4, 0x0f0f_0f0f);
    let v = swap(v, 8, 0x00ff_00ff);
    (v >> 16) | (v << 16)
}

/// [`owen_hash_reversed`] in 8 lanes, a seed per lane (the same wrapping steps).
#[inline(always)]
fn owen_hash_reversed_x8(x: u32x8, seed: u32x8) -> u32x8 {
    let k = |c: u32| u32x8::splat(c);
    let mut x = x;
    x ^= x * k(0x9e37_79ba);
    x += seed;
    x *= (seed >> 15) | k(1);
    x ^= x * k(0x2545_f492);
    x += ((seed << 11) | (seed >> 21)) ^ k(0x68e3_1da4);
    x ^= x * k(0x5851_f42e);
    x ^= x * k(0x7feb_352a);
    x
}

/// [`unit_f32`] in 8 lanes (24-bit integers are exact in f32).
#[inline(always)]
fn unit_f32_x8(bits: u32x8) -> f32x8 {
    f32x8::from_i32x8(bytemuck::cast::<u32x8, i32x8>(bits >> 8)) * f32x8::splat(1.0 / 16_777_216.0)
}

/// Eight lanes of [`sobol_owen_2d`] (lane `l`: point `index[l]` of sequence `keys[l]`), bit for bit, in
/// vector operations. With `r(x)` the bit reversal and `h_s` the reversed-order hash, the scalar path
/// computes `shuffled = r(h_i(r(index)))`, `x = r(h_x(r(r(shuffled))))` and `y = r(h_y(r(M shuffled)))`
/// (`M` the generator matrix); here `r(r(shuffled)) = shuffled`, and `r(M v)` is the superset transform
/// of `v`'s bits (bit `j` of `r(M v)` is the xor of `v`'s bits `k` with `C(k, j)` odd, that is with
/// `j` a bit subset of `k`: Lucas), five shift-and-xor steps instead of the byte tables.
#[inline(always)]
pub fn sobol_owen_2d_x8(keys: &[u64; 8], index: &[u32; 8]) -> [f32x8; 2] {
    let mut s = [[0u32; 8]; 3];
    for l in 0..8 {
        let [a, b, c] = if l > 0 && keys[l] == keys[l - 1] { [s[0][l - 1], s[1][l - 1], s[2][l - 1]] } else { seeds(keys[l]) };
        (s[0][l], s[1][l], s[2][l]) = (a, b, c);
    }
    let [s_index, s_x, s_y] = s.map(u32x8::from);
    let shuffled = reverse_bits_x8(owen_hash_reversed_x8(reverse_bits_x8(u32x8::from(*index)), s_index));
    let mut z = shuffled;
    for (sh, m) in [(1, 0x5555_5555u32), (2, 0x3333_3333), (4, 0x0f0f_0f0f), (8, 0x00ff_00ff), (16, 0x0000_ffff)] {
        z ^= (z >> sh) & u32x8::splat(m);
    }
    let x = reverse_bits_x8(owen_hash_reversed_x8(shuffled, s_x));
    let y = reverse_bits_x8(owen_hash_reversed_x8(z, s_y));
    [unit_f32_x8(x), unit_f32_x8(y)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sobol_first_points_match_known_sequence() {
        // Unscrambled 2D Sobol in index order (x = van der Corput, y = Pascal-matrix dimension).
        let expect = [(0.0, 0.0), (0.5, 0.5), (0.25, 0.75), (0.75, 0.25), (0.125, 0.625), (0.625, 0.125), (0.375, 0.375), (0.875, 0.875)];
        for (i, &(ex, ey)) in expect.iter().enumerate() {
            let [x, y] = sobol_2d_u32(i as u32);
            assert_eq!((unit_f32(x), unit_f32(y)), (ex, ey), "point {i}");
        }
    }

    #[test]
    fn byte_tables_match_bitwise_generator() {
        let mut x = 0x1234_5678u32;
        for i in (0..4096u32).chain([u32::MAX, 1 << 31, 0x8000_0001]) {
            assert_eq!(sobol_2d_u32(i)[1], sobol_dim1_bitwise(i), "index {i}");
            x = x.wrapping_mul(0x9e37_79b9).wrapping_add(0x7f4a_7c15);
            assert_eq!(sobol_2d_u32(x)[1], sobol_dim1_bitwise(x), "index {x}");
        }
    }

    /// The defining property of the scramble: for any seed, two values share exactly as many leading
    /// digits after scrambling as before.
    #[test]
    fn owen_scramble_preserves_common_prefix() {
        let vals = [0u32, 1, 0x8000_0000, 0x4000_0000, 0xc000_0001, 0x1234_5678, 0x1234_5679];
        for seed in 0..2000u32 {
            let seed = seed.wrapping_mul(0x9e37_79b9);
            for &a in &vals {
                for &b in &vals {
                    let before = (a ^ b).leading_zeros();
                    let after = (owen_scramble(a, seed) ^ owen_scramble(b, seed)).leading_zeros();
                    assert_eq!(before, after, "a={a:#x} b={b:#x} seed={seed:#x}");
                }
            }
        }
    }

    #[test]
    fn one_d_equals_scrambled_van_der_corput() {
        for key in [0u64, 1, 0xdead_beef_cafe_f00d] {
            let [s_index, s_x, _] = seeds(key);
            for i in 0..64 {
                let vdc = owen_scramble(i, s_index).reverse_bits();
                assert_eq!(sobol_owen_1d(key, i), unit_f32(owen_scramble(vdc, s_x)));
            }
        }
    }

    /// The 8-lane points are the scalar ones, bit for bit: one key and keys per lane, indices small,
    /// consecutive, random and at the ends of the range.
    #[test]
    fn eight_lanes_equal_the_scalar_points() {
        let mut h = 0x1234_5678_9abc_def0u64;
        let mut next = || {
            h = mix64(h.wrapping_add(0x9e37_79b9_7f4a_7c15));
            h
        };
        for case in 0..4000u32 {
            let one = next();
            // One key for all lanes in even cases; in odd ones, every third lane's key is shared.
            let keys: [u64; 8] = std::array::from_fn(|l| if case % 2 == 0 || l % 3 == 0 { one } else { next() });
            let index: [u32; 8] = match case % 4 {
                0 => std::array::from_fn(|l| case * 8 + l as u32),
                1 => std::array::from_fn(|_| next() as u32),
                2 => std::array::from_fn(|l| [0, 1, u32::MAX, 1 << 31, 0x8000_0001, 4095, 4096, 7][l]),
                _ => std::array::from_fn(|l| (next() as u32) >> (l * 4)),
            };
            let [x, y] = sobol_owen_2d_x8(&keys, &index);
            let (x, y) = (x.to_array(), y.to_array());
            for l in 0..8 {
                let [sx, sy] = sobol_owen_2d(keys[l], index[l]);
                assert_eq!((x[l].to_bits(), y[l].to_bits()), (sx.to_bits(), sy.to_bits()), "case {case} lane {l}: index {}", index[l]);
            }
        }
    }
}
