//! Seeded mutations of scene and profile text: truncation, byte flips, hostile values, unknown keys,
//! wrong keys, duplicated / deleted / swapped lines, non-UTF-8 bytes.

/// SplitMix64: a small seeded generator (the fuzzer must be reproducible from its seed alone).
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    pub fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
    pub fn pick<'a, T>(&mut self, xs: &'a [T]) -> &'a T {
        &xs[self.below(xs.len())]
    }
}

/// Values no field should accept silently, and some it should: the loader must answer each with a
/// located error or a scene that renders.
pub const HOSTILE_VALUES: &[&str] = &[
    "1e39",
    "-1e39",
    "-0",
    "-0.0",
    "nan",
    "+nan",
    "-nan",
    "inf",
    "+inf",
    "-inf",
    "3.4e38",
    "-3.4e38",
    "1e-45",
    "0",
    "1",
    "9223372036854775807",
    "-9223372036854775808",
    "99999999999999999999",
    "1e300",
    "0x7fffffff",
    "\"\"",
    "\"str\"",
    "\"\\u0000\"",
    "[]",
    "[1]",
    "[1, 2]",
    "[1, 2, 3, 4]",
    "[nan, nan, nan]",
    "[1e39, 0, 0]",
    "[3e38, 3e38, 3e38]",
    "[-3e38, 0, 3e38]",
    "[-0.0, -0.0, -0.0]",
    "[0, 0, 0]",
    "[inf, -inf, nan]",
    "[\"a\", 1, 2]",
    "[[1, 2, 3]]",
    "{}",
    "{ a = 1 }",
    "true",
    "false",
    "1979-05-27T07:32:00Z",
    "07:32:00",
    "1979-05-27",
];

/// Keys of the format (to put a valid key where it does not apply) and keys it does not have.
pub const KEYS: &[&str] = &[
    "width",
    "height",
    "background",
    "position",
    "look_at",
    "up",
    "fov",
    "aperture",
    "focus_distance",
    "shutter",
    "type",
    "albedo",
    "checker",
    "tint",
    "radiance",
    "roughness",
    "ior",
    "cauchy",
    "abbe",
    "absorption",
    "transmittance",
    "transmittance_distance",
    "thin",
    "fresnel",
    "use",
    "material",
    "center",
    "radius",
    "point",
    "normal",
    "min",
    "max",
    "origin",
    "u",
    "v",
    "radius_top",
    "major_radius",
    "minor_radius",
    "motion",
    "transform",
    "op",
    "children",
    "hole",
    "intensity",
    "scale",
    "rotate",
    "translate",
    "spp",
    "max_depth",
    "colour",
    "radious",
    "Type",
    "ＵＮＩ",
    "",
];

/// One random mutation of `text` (as bytes: the result need not be UTF-8).
pub fn mutate(rng: &mut Rng, text: &str) -> (Vec<u8>, &'static str) {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let n = lines.len().max(1);
    let what = rng.below(10);
    let bytes = match what {
        // Truncate anywhere (possibly inside a string or a multi-byte character).
        0 => {
            let b = text.as_bytes();
            return (b[..rng.below(b.len() + 1)].to_vec(), "truncate");
        }
        // Flip 1..8 random bits.
        1 => {
            let mut b = text.as_bytes().to_vec();
            for _ in 0..1 + rng.below(8) {
                let i = rng.below(b.len());
                b[i] ^= 1 << rng.below(8);
            }
            return (b, "bit flips");
        }
        // Replace the value of a random `key = value` line by a hostile value.
        2..=4 => {
            let candidates: Vec<usize> = (0..lines.len()).filter(|&i| lines[i].contains(" = ")).collect();
            if let Some(&i) = candidates.get(rng.below(candidates.len())) {
                let key = lines[i].split(" = ").next().unwrap().to_string();
                lines[i] = format!("{key} = {}", rng.pick(HOSTILE_VALUES));
            }
            return (lines.join("\n").into_bytes(), "hostile value");
        }
        // Rename a key to another key of the format (or to a key it does not have).
        5 => {
            let candidates: Vec<usize> = (0..lines.len()).filter(|&i| lines[i].contains(" = ")).collect();
            if let Some(&i) = candidates.get(rng.below(candidates.len())) {
                let value = lines[i].split_once(" = ").unwrap().1.to_string();
                lines[i] = format!("{} = {value}", rng.pick(KEYS));
            }
            return (lines.join("\n").into_bytes(), "renamed key");
        }
        // Insert an unknown or misplaced key after a random line.
        6 => {
            let i = rng.below(n);
            lines.insert(i.min(lines.len()), format!("{} = {}", rng.pick(KEYS), rng.pick(HOSTILE_VALUES)));
            lines.join("\n").into_bytes()
        }
        // Duplicate, delete or swap lines.
        7 => {
            let (i, j) = (rng.below(n).min(lines.len().saturating_sub(1)), rng.below(n).min(lines.len().saturating_sub(1)));
            match rng.below(3) {
                0 => {
                    let l = lines[i].clone();
                    lines.insert(j, l);
                }
                1 => {
                    lines.remove(i);
                }
                _ => lines.swap(i, j),
            }
            lines.join("\n").into_bytes()
        }
        // Insert bytes that are not UTF-8.
        8 => {
            let mut b = text.as_bytes().to_vec();
            let bad: &[&[u8]] = &[b"\xff", b"\xc3\x28", b"\xe2\x82", b"\xf0\x9f\x98", b"\x80", b"\xed\xa0\x80"];
            let at = rng.below(b.len() + 1);
            b.splice(at..at, rng.pick(bad).iter().copied());
            return (b, "non-UTF-8");
        }
        // Several of the above at once.
        _ => {
            let (a, _) = mutate(rng, text);
            let a = String::from_utf8_lossy(&a).into_owned();
            return (mutate(rng, &a).0, "compound");
        }
    };
    (bytes, if what == 6 { "inserted key" } else { "lines" })
}
