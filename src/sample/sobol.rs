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
}
