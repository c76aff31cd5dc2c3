//! XXH64 (Yann Collet's xxHash, 64-bit variant, seed 0), written from the published specification
//! (`doc/xxhash_spec.md` in the xxHash repository). It checks film files: fast enough (several GB/s) that
//! a checkpoint of a large film is not slowed by it, and a standard function, so a film can be checked
//! with an independent tool (`xxhsum -H64`) as well.

const P1: u64 = 0x9E37_79B1_85EB_CA87;
const P2: u64 = 0xC2B2_AE3D_27D4_EB4F;
const P3: u64 = 0x1656_67B1_9E37_79F9;
const P4: u64 = 0x85EB_CA77_C2B2_AE63;
const P5: u64 = 0x27D4_EB2F_1656_67C5;

#[inline]
fn round(acc: u64, lane: u64) -> u64 {
    acc.wrapping_add(lane.wrapping_mul(P2)).rotate_left(31).wrapping_mul(P1)
}

#[inline]
fn merge_round(acc: u64, v: u64) -> u64 {
    (acc ^ round(0, v)).wrapping_mul(P1).wrapping_add(P4)
}

#[inline]
fn u64_at(b: &[u8], i: usize) -> u64 {
    u64::from_le_bytes(b[i..i + 8].try_into().unwrap())
}

/// XXH64 of `data` with seed 0.
pub fn xxh64(data: &[u8]) -> u64 {
    let mut h = Xxh64::new();
    h.update(data);
    h.finish()
}

/// XXH64 (seed 0) of bytes given piece by piece: [`Xxh64::finish`] after any split of the data into
/// [`Xxh64::update`]s equals [`xxh64`] of the whole (a film is hashed as it is written or read, never
/// held whole in memory).
#[derive(Clone, Debug)]
pub struct Xxh64 {
    acc: [u64; 4],
    /// Bytes of an unfinished 32-byte stripe.
    buf: [u8; 32],
    buffered: usize,
    len: u64,
}

impl Default for Xxh64 {
    fn default() -> Self {
        Self::new()
    }
}

impl Xxh64 {
    pub fn new() -> Xxh64 {
        let seed = 0u64;
        let acc = [seed.wrapping_add(P1).wrapping_add(P2), seed.wrapping_add(P2), seed, seed.wrapping_sub(P1)];
        Xxh64 { acc, buf: [0; 32], buffered: 0, len: 0 }
    }

    #[inline(always)]
    fn stripe(acc: &mut [u64; 4], s: &[u8]) {
        for (k, a) in acc.iter_mut().enumerate() {
            *a = round(*a, u64_at(s, 8 * k));
        }
    }

    pub fn update(&mut self, mut data: &[u8]) {
        self.len += data.len() as u64;
        if self.buffered > 0 {
            let n = (32 - self.buffered).min(data.len());
            self.buf[self.buffered..self.buffered + n].copy_from_slice(&data[..n]);
            self.buffered += n;
            data = &data[n..];
            if self.buffered < 32 {
                return;
            }
            let buf = self.buf;
            Self::stripe(&mut self.acc, &buf);
            self.buffered = 0;
        }
        let whole = data.len() / 32 * 32;
        let mut acc = self.acc;
        for s in data[..whole].chunks_exact(32) {
            Self::stripe(&mut acc, s);
        }
        self.acc = acc;
        let rest = &data[whole..];
        self.buf[..rest.len()].copy_from_slice(rest);
        self.buffered = rest.len();
    }

    pub fn finish(&self) -> u64 {
        let len = self.len;
        let mut h = if len >= 32 {
            let v = self.acc;
            let mut h =
                v[0].rotate_left(1).wrapping_add(v[1].rotate_left(7)).wrapping_add(v[2].rotate_left(12)).wrapping_add(v[3].rotate_left(18));
            for acc in v {
                h = merge_round(h, acc);
            }
            h
        } else {
            0u64.wrapping_add(P5)
        };
        h = h.wrapping_add(len);
        let data = &self.buf[..self.buffered];
        let mut i = 0;
        while i + 8 <= data.len() {
            h ^= round(0, u64_at(data, i));
            h = h.rotate_left(27).wrapping_mul(P1).wrapping_add(P4);
            i += 8;
        }
        if i + 4 <= data.len() {
            h ^= (u32::from_le_bytes(data[i..i + 4].try_into().unwrap()) as u64).wrapping_mul(P1);
            h = h.rotate_left(23).wrapping_mul(P2).wrapping_add(P3);
            i += 4;
        }
        for &b in &data[i..] {
            h ^= (b as u64).wrapping_mul(P5);
            h = h.rotate_left(11).wrapping_mul(P1);
        }
        h ^= h >> 33;
        h = h.wrapping_mul(P2);
        h ^= h >> 29;
        h = h.wrapping_mul(P3);
        h ^ (h >> 32)
    }
}

#[cfg(test)]
mod tests {
    use super::xxh64;

    #[test]
    fn matches_reference_values() {
        // Reference values from the xxHash command-line tool: `printf abc | xxhsum -H64`, and for the
        // patterns, bytes (7 i + 3) mod 256 for i in 0..n piped to `xxhsum -H64`. The lengths cover the
        // short path, exactly one 32-byte stripe, and stripes plus 8-, 4- and 1-byte tails.
        assert_eq!(xxh64(b""), 0xef46db3751d8e999);
        assert_eq!(xxh64(b"abc"), 0x44bc2cf5ad770999);
        let pattern = |n: usize| (0..n).map(|i| ((i * 7 + 3) % 256) as u8).collect::<Vec<u8>>();
        assert_eq!(xxh64(&pattern(31)), 0xa2aa5f33cc4a6119);
        assert_eq!(xxh64(&pattern(32)), 0x23c3c17ef790fd97);
        assert_eq!(xxh64(&pattern(45)), 0x86faee00897c4b41);
        assert_eq!(xxh64(&pattern(1000)), 0x5f235fa033f1a3fb);
    }

    /// The one-shot function as it was (before the streaming hasher): the reference the streaming one
    /// is held to.
    fn xxh64_whole(data: &[u8]) -> u64 {
        use super::*;
        let len = data.len();
        let mut i = 0;
        let mut h = if len >= 32 {
            let mut v = [P1.wrapping_add(P2), P2, 0, 0u64.wrapping_sub(P1)];
            while i + 32 <= len {
                for (k, acc) in v.iter_mut().enumerate() {
                    *acc = round(*acc, u64_at(data, i + 8 * k));
                }
                i += 32;
            }
            let mut h =
                v[0].rotate_left(1).wrapping_add(v[1].rotate_left(7)).wrapping_add(v[2].rotate_left(12)).wrapping_add(v[3].rotate_left(18));
            for acc in v {
                h = merge_round(h, acc);
            }
            h
        } else {
            P5
        };
        h = h.wrapping_add(len as u64);
        while i + 8 <= len {
            h ^= round(0, u64_at(data, i));
            h = h.rotate_left(27).wrapping_mul(P1).wrapping_add(P4);
            i += 8;
        }
        if i + 4 <= len {
            h ^= (u32::from_le_bytes(data[i..i + 4].try_into().unwrap()) as u64).wrapping_mul(P1);
            h = h.rotate_left(23).wrapping_mul(P2).wrapping_add(P3);
            i += 4;
        }
        for &b in &data[i..] {
            h ^= (b as u64).wrapping_mul(P5);
            h = h.rotate_left(11).wrapping_mul(P1);
        }
        h ^= h >> 33;
        h = h.wrapping_mul(P2);
        h ^= h >> 29;
        h = h.wrapping_mul(P3);
        h ^ (h >> 32)
    }

    /// Any split of the data into updates gives the one-shot hash: every length to 200 split at every
    /// point, and a 10,000-byte buffer in pieces of every size from 1 to 100.
    #[test]
    fn streaming_equals_one_shot() {
        let data: Vec<u8> = (0..10_000u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8).collect();
        for n in 0..200 {
            let want = xxh64_whole(&data[..n]);
            assert_eq!(xxh64(&data[..n]), want, "length {n}");
            for cut in 0..=n {
                let mut h = super::Xxh64::new();
                h.update(&data[..cut]);
                h.update(&data[cut..n]);
                assert_eq!(h.finish(), want, "length {n} cut at {cut}");
            }
        }
        let want = xxh64_whole(&data);
        for piece in 1..=100 {
            let mut h = super::Xxh64::new();
            data.chunks(piece).for_each(|c| h.update(c));
            assert_eq!(h.finish(), want, "pieces of {piece}");
        }
    }
}
