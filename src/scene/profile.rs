//! Quality profiles: a named, complete choice of sample counts and strategies (`profiles/*.toml`).
//! Command-line flags override single fields through [`Profile::set`].

use super::error::{read_text, InputError, Source};
use crate::sample::strategy::lowercase_hint;
use crate::sample::{Filter, Strategy};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// How a dielectric hit continues: both children weighted by Fresnel, or one picked by Fresnel probability.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Branching {
    /// Whitted's split: trace reflection and refraction, each weighted by R and T.
    Split,
    /// Russian roulette: trace one, chosen with probability R (weights cancel).
    Roulette,
}

impl Branching {
    /// The name profile files use.
    pub fn name(self) -> &'static str {
        match self {
            Branching::Split => "split",
            Branching::Roulette => "roulette",
        }
    }
}

/// Which lights a shading point samples (next-event estimation): every light, or one light picked per
/// shading point with a probability, its contribution divided by that probability (unbiased). See
/// `wavefront/pick.rs`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum LightSelection {
    /// Every light at every shading point (Cook 1984; the cost grows with the number of lights).
    All,
    /// One light, each with the same probability.
    Uniform,
    /// One light, with probability proportional to its emitted power.
    Power,
    /// One light, with probability proportional to its power over its squared distance from the point
    /// (zero behind a one-sided light): near lights are picked more often.
    Local,
    /// One light, by descending a tree of the lights with bounds of `local`'s importance at each node:
    /// O(log L) per point where `local` is O(L).
    Tree,
}

impl LightSelection {
    pub const ALL: [LightSelection; 5] =
        [LightSelection::All, LightSelection::Uniform, LightSelection::Power, LightSelection::Local, LightSelection::Tree];

    /// The name profile files use.
    pub fn name(self) -> &'static str {
        match self {
            LightSelection::All => "all",
            LightSelection::Uniform => "uniform",
            LightSelection::Power => "power",
            LightSelection::Local => "local",
            LightSelection::Tree => "tree",
        }
    }
}

fn default_selection() -> LightSelection {
    LightSelection::All
}

fn is_all(s: &LightSelection) -> bool {
    *s == LightSelection::All
}

/// A count written as text (`--spp`, `--set spp=`): what is wrong with it named as what it is (negative,
/// fractional, too large, or digits needed: `1e3`, `4.0`), not as "not in 0..=4294967295". Its upper
/// bound `max` is only quoted (the profile's validation checks it, and 0, with its reason).
pub fn parse_count(v: &str, max: u32) -> Result<u32, String> {
    let t = v.trim();
    t.parse::<u32>().map_err(|_| match t.parse::<f64>() {
        Ok(x) if !x.is_finite() => format!("`{v}` is not a count (a whole number, at most {max})"),
        Ok(x) if x < 0.0 => format!("`{v}` is negative (a count: a whole number, at most {max})"),
        Ok(x) if x.fract() != 0.0 => format!("`{v}` is not a whole number (a count, at most {max})"),
        Ok(x) if x > u32::MAX as f64 => format!("`{v}` is too large (at most {max})"),
        Ok(x) => format!("`{v}`: write a count in digits (`{}`)", x as u64),
        Err(_) => format!("`{v}` is not a number (a count: a whole number, at most {max})"),
    })
}

/// Hard limits that protect the machine; exceeding one is an input error, not an out-of-memory crash.
pub const MAX_SPP: u32 = 1 << 20;
pub const MAX_LIGHT_SAMPLES: u32 = 4096;
pub const MAX_DEPTH: u32 = 1024;

#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Profile {
    /// The name the render summary prints; a file without one is named after the file
    /// (`Profile::name_after`).
    #[serde(default)]
    pub name: String,
    /// Camera samples per pixel.
    pub spp: u32,
    pub pixel_strategy: Strategy,
    #[serde(default = "default_filter")]
    pub filter: Filter,
    /// Samples per area light per shading point.
    pub light_samples: u32,
    pub light_strategy: Strategy,
    /// Every light per shading point, or one picked light (`uniform`, `power`, `local`). Left out of the
    /// film's profile record when `all`, so that films of renders before it existed still resume.
    #[serde(default = "default_selection", skip_serializing_if = "is_all")]
    pub light_selection: LightSelection,
    #[serde(default = "default_strategy")]
    pub lens_strategy: Strategy,
    #[serde(default = "default_strategy")]
    pub time_strategy: Strategy,
    #[serde(default = "default_strategy")]
    pub glossy_strategy: Strategy,
    /// Directions of diffuse bounces (cosine-weighted); only used when `diffuse_depth > 0`.
    #[serde(default = "default_strategy")]
    pub diffuse_strategy: Strategy,
    /// Wavelength of a camera sample; only used by scenes with a dispersive index.
    #[serde(default = "default_strategy")]
    pub wavelength_strategy: Strategy,
    /// Specular / glossy / diffuse bounces after the camera ray.
    pub max_depth: u32,
    /// Diffuse bounces (0: classic distribution ray tracing; > 0: path tracing with Russian roulette).
    #[serde(default)]
    pub diffuse_depth: u32,
    #[serde(default = "default_branching")]
    pub branching: Branching,
    /// Paths whose throughput falls below this play Russian roulette (unbiased cut-off).
    #[serde(default = "default_cutoff")]
    pub throughput_cutoff: f32,
    /// Non-physical: shadow rays pass through dielectrics, attenuated by their transmittance.
    #[serde(default)]
    pub transmissive_shadows: bool,
}

fn default_filter() -> Filter {
    Filter::Box
}
fn default_strategy() -> Strategy {
    Strategy::Jittered
}
fn default_branching() -> Branching {
    Branching::Split
}
fn default_cutoff() -> f32 {
    1e-3
}

/// The profiles shipped in `profiles/`, embedded so the binary works from any directory.
pub const BUILTIN: [(&str, &str); 9] = [
    ("preview", include_str!("../../profiles/preview.toml")),
    ("final", include_str!("../../profiles/final.toml")),
    ("reference", include_str!("../../profiles/reference.toml")),
    ("bench", include_str!("../../profiles/bench.toml")),
    ("light1", include_str!("../../profiles/light1.toml")),
    ("light9", include_str!("../../profiles/light9.toml")),
    ("light36", include_str!("../../profiles/light36.toml")),
    ("light100", include_str!("../../profiles/light100.toml")),
    ("caustic", include_str!("../../profiles/caustic.toml")),
];

impl Profile {
    /// Parse profile text; `path` is used in error messages.
    pub fn parse(path: &Path, text: &str) -> Result<Profile, InputError> {
        let src = Source { path, text };
        let mut p: Profile = toml::from_str(text).map_err(|e| src.from_toml(&e))?;
        p.name_after(path);
        p.validate().map_err(|(field, msg)| {
            let span = find_key(text, field).unwrap_or(0..0);
            src.error(span, field, msg)
        })?;
        Ok(p)
    }

    /// `--profile NAME|PATH`: a path to a file, else `profiles/NAME.toml` in the working directory, else
    /// the built-in copy of a shipped profile.
    pub fn load(name_or_path: &str) -> Result<Profile, InputError> {
        let (path, text) = Self::find(name_or_path)?;
        Profile::parse(&path, &text)
    }

    /// [`Profile::load`], then the overrides `pairs` (`--set` and the flags, in order), then the checks
    /// of the result: a file's combination that the overrides make valid is valid (`max_depth = 4` with
    /// `diffuse_depth = 9`, fixed by `--set max_depth=9`). Errors are whole messages: a field the
    /// overrides set is the command line's error, any other the file's, at its line.
    /// `overrides` sees the file's profile as read (a flag's meaning may depend on it).
    pub fn load_with(name_or_path: &str, overrides: impl FnOnce(&Profile) -> Vec<(String, String)>) -> Result<Profile, String> {
        let (path, text) = Self::find(name_or_path).map_err(|e| e.to_string())?;
        let src = Source { path: &path, text: &text };
        let mut p: Profile = toml::from_str(&text).map_err(|e| src.from_toml(&e).to_string())?;
        p.name_after(&path);
        let pairs = overrides(&p);
        let mut set = Vec::new();
        for (k, v) in general_strategy_first(pairs.iter().map(|(k, v)| (k.trim(), v.as_str()))) {
            p.set_field(k, v).map_err(|e| format!("command line: {e}"))?;
            set.push(k);
        }
        p.validate().map_err(|(field, msg)| {
            // (`strategy` sets every strategy field; none of them has a check of its own.) A check of a
            // combination is the command line's when an override set any field of it, named first.
            let in_file = || src.error(find_key(&text, field).unwrap_or(0..0), field, msg.clone());
            if set.contains(&field) {
                format!("command line: {field}: {msg}")
            } else if let Some(f) = combined_with(field).iter().find(|f| set.contains(f)) {
                let e = in_file();
                format!("command line: {f}: {field} ({}:{}): {msg}", e.file.display(), e.line)
            } else {
                in_file().to_string()
            }
        })?;
        Ok(p)
    }

    /// The path errors name and the text of `--profile NAME|PATH` (see [`Profile::load`]).
    fn find(name_or_path: &str) -> Result<(PathBuf, String), InputError> {
        let as_path = PathBuf::from(name_or_path);
        let flag_error =
            |message: String| InputError { file: PathBuf::from("command line"), line: 0, column: 0, field: "--profile".into(), message };
        // (A directory of a shipped profile's name in the working directory does not hide that profile.)
        let local = PathBuf::from("profiles").join(format!("{name_or_path}.toml"));
        let shipped = BUILTIN.iter().any(|(n, _)| *n == name_or_path) || local.is_file();
        if as_path.is_dir() && (name_or_path.ends_with(".toml") || !shipped) {
            return Err(flag_error(format!(
                "`{name_or_path}` is a directory, not a profile file (give a .toml file or a shipped profile name)"
            )));
        }
        if as_path.exists() && !as_path.is_file() && !shipped {
            return Err(flag_error(format!("`{name_or_path}` is not a regular file (give a .toml file or a shipped profile name)")));
        }
        if name_or_path.ends_with(".toml") || as_path.is_file() {
            let text = read_text(&as_path)?;
            return Ok((as_path, text));
        }
        if local.is_file() {
            let text = read_text(&local)?;
            return Ok((local, text));
        }
        if let Some((_, text)) = BUILTIN.iter().find(|(n, _)| *n == name_or_path) {
            return Ok((PathBuf::from(format!("<built-in profile {name_or_path}>")), text.to_string()));
        }
        Err(flag_error(format!(
            "no profile file `{name_or_path}` or `{}`, and no shipped profile of that name (shipped: {})",
            local.display(),
            BUILTIN.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", ")
        )))
    }

    /// A profile file without a `name` (or with `name = ""`) is named after its file: `my_preview` for
    /// `my_preview.toml` (the summary printed a blank name).
    fn name_after(&mut self, path: &Path) {
        if self.name.trim().is_empty() {
            self.name = path.file_stem().map_or_else(String::new, |s| s.to_string_lossy().into_owned());
        }
    }

    pub fn builtin(name: &str) -> Profile {
        Profile::load(name).expect("shipped profiles are valid")
    }

    /// Range checks; returns the field name and the problem.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        if self.spp == 0 || self.spp > MAX_SPP {
            return Err(("spp", format!("must be in 1..={MAX_SPP}, got {}", self.spp)));
        }
        if self.light_samples == 0 || self.light_samples > MAX_LIGHT_SAMPLES {
            return Err(("light_samples", format!("must be in 1..={MAX_LIGHT_SAMPLES}, got {}", self.light_samples)));
        }
        if self.max_depth > MAX_DEPTH {
            return Err(("max_depth", format!("must be at most {MAX_DEPTH}, got {}", self.max_depth)));
        }
        if self.diffuse_depth > self.max_depth {
            return Err(("diffuse_depth", format!("must not exceed max_depth ({}), got {}", self.max_depth, self.diffuse_depth)));
        }
        if !(self.throughput_cutoff.is_finite() && (0.0..1.0).contains(&self.throughput_cutoff)) {
            let rounded = if self.throughput_cutoff == 1.0 { " (as an f32: a value this close to 1 rounds to 1)" } else { "" };
            return Err(("throughput_cutoff", format!("must be in [0, 1), got {}{rounded}", self.throughput_cutoff)));
        }
        if self.throughput_cutoff == 0.0 && self.branching == Branching::Split {
            return Err((
                "throughput_cutoff",
                "with branching = \"split\", a cutoff of 0 traces every branch of the ray tree: it doubles at each glass \
                 interface, up to 2^max_depth rays per camera sample (memory runs out); use a cutoff > 0 (default 1e-3: the \
                 tree then stays within about 3 / cutoff rays per bounce and camera sample) or branching = \"roulette\""
                    .into(),
            ));
        }
        Ok(())
    }

    /// Override one field ([`Profile::set_all`] of one pair). On error the profile is left unchanged.
    pub fn set(&mut self, key: &str, value: &str) -> Result<(), String> {
        self.set_all([(key, value)])
    }

    /// Several overrides at once (`--set` flags, in order), validated together after the last: so that
    /// `max_depth=0` may come before the `diffuse_depth=0` that makes it valid. On error nothing changes.
    pub fn set_all<'a>(&mut self, pairs: impl IntoIterator<Item = (&'a str, &'a str)>) -> Result<(), String> {
        let mut p = self.clone();
        for (k, v) in general_strategy_first(pairs.into_iter().map(|(k, v)| (k.trim(), v))) {
            p.set_field(k, v)?;
        }
        p.validate().map_err(|(f, m)| format!("{f}: {m}"))?;
        *self = p;
        Ok(())
    }

    fn set_field(&mut self, key: &str, value: &str) -> Result<(), String> {
        fn num<T: std::str::FromStr>(key: &str, v: &str) -> Result<T, String> {
            v.trim().parse().map_err(|_| format!("{key}: `{v}` is not a valid number"))
        }
        fn count(key: &str, v: &str, max: u32) -> Result<u32, String> {
            parse_count(v, max).map_err(|e| format!("{key}: {e}"))
        }
        // Names are exact and lowercase, as in profile files (`centre` is accepted for `center` there too).
        fn strat(key: &str, v: &str) -> Result<Strategy, String> {
            Strategy::parse_or_explain(v.trim()).map_err(|e| format!("{key}: {e}"))
        }
        match key {
            "spp" => self.spp = count(key, value, MAX_SPP)?,
            "light_samples" => self.light_samples = count(key, value, MAX_LIGHT_SAMPLES)?,
            "max_depth" => self.max_depth = count(key, value, MAX_DEPTH)?,
            "diffuse_depth" => self.diffuse_depth = count(key, value, MAX_DEPTH)?,
            "throughput_cutoff" => self.throughput_cutoff = num(key, value)?,
            "transmissive_shadows" => {
                self.transmissive_shadows = value.trim().parse().map_err(|_| format!("{key}: expected true or false"))?
            }
            "pixel_strategy" => self.pixel_strategy = strat(key, value)?,
            "light_strategy" => self.light_strategy = strat(key, value)?,
            "lens_strategy" => self.lens_strategy = strat(key, value)?,
            "time_strategy" => self.time_strategy = strat(key, value)?,
            "glossy_strategy" => self.glossy_strategy = strat(key, value)?,
            "diffuse_strategy" => self.diffuse_strategy = strat(key, value)?,
            "wavelength_strategy" => self.wavelength_strategy = strat(key, value)?,
            "strategy" => {
                let s = strat(key, value)?;
                self.pixel_strategy = s;
                self.light_strategy = s;
                self.lens_strategy = s;
                self.time_strategy = s;
                self.glossy_strategy = s;
                self.diffuse_strategy = s;
                self.wavelength_strategy = s;
            }
            "branching" => {
                self.branching = match value.trim() {
                    "split" => Branching::Split,
                    "roulette" => Branching::Roulette,
                    t => return Err(format!("{key}: expected split or roulette, got `{value}`{}", lowercase_hint(t))),
                }
            }
            "light_selection" => {
                let t = value.trim();
                self.light_selection = LightSelection::ALL
                    .into_iter()
                    .find(|s| s.name() == t)
                    .ok_or_else(|| format!("{key}: expected all, uniform, power, local or tree, got `{value}`{}", lowercase_hint(t)))?
            }
            "filter" => {
                let t = value.trim();
                self.filter = Filter::ALL
                    .into_iter()
                    .find(|f| f.name() == t)
                    .ok_or_else(|| format!("{key}: expected box, tent or gaussian, got `{value}`{}", lowercase_hint(t)))?
            }
            "name" => self.name = value.trim().to_string(),
            _ => return Err(format!("unknown profile field `{key}`")),
        }
        Ok(())
    }
}

/// The overrides with every general `strategy` before the single ones (`pixel_strategy`, ...), each
/// group in the given order: a single strategy refines the general one whichever order they come in.
fn general_strategy_first<'a>(pairs: impl IntoIterator<Item = (&'a str, &'a str)>) -> Vec<(&'a str, &'a str)> {
    let (mut general, rest): (Vec<_>, Vec<_>) = pairs.into_iter().partition(|(k, _)| *k == "strategy");
    general.extend(rest);
    general
}

/// The other fields of the checks of a combination that [`Profile::validate`] reports under `field`.
fn combined_with(field: &str) -> &'static [&'static str] {
    match field {
        "diffuse_depth" => &["max_depth"],
        "throughput_cutoff" => &["branching"],
        _ => &[],
    }
}

/// Byte span of `key = ...` at the start of a line, the key bare, `"quoted"` or `'literal'` (for
/// validation errors on plain fields; a quoted key was reported at 1:1).
fn find_key(text: &str, key: &str) -> Option<std::ops::Range<usize>> {
    let mut offset = 0;
    for line in text.split_inclusive('\n') {
        let t = line.trim_start();
        for q in ["", "\"", "'"] {
            let Some(rest) = t.strip_prefix(q).and_then(|r| r.strip_prefix(key)).and_then(|r| r.strip_prefix(q)) else { continue };
            if rest.trim_start().starts_with('=') {
                let start = offset + (line.len() - t.len());
                return Some(start..start + key.len() + 2 * q.len());
            }
        }
        offset += line.len();
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quoted_keys_are_found_at_their_line() {
        let text = "name = \"x\"\n# spp = 1\n\"spp\" = 0\n'max_depth' = 3\nspp_x = 1\n";
        assert_eq!(find_key(text, "spp").map(|r| &text[r]), Some("\"spp\""));
        assert_eq!(find_key(text, "max_depth").map(|r| &text[r]), Some("'max_depth'"));
        assert_eq!(find_key("spp_x = 1\n  spp= 2\n", "spp"), Some(12..15));
        assert_eq!(find_key("\"spp' = 1\n", "spp"), None);
    }

    #[test]
    fn every_builtin_profile_parses_and_is_named_after_itself() {
        for (name, _) in BUILTIN {
            let p = Profile::builtin(name);
            assert_eq!(p.name, name);
        }
    }

    #[test]
    fn set_rejects_out_of_range_and_unknown_fields() {
        let mut p = Profile::builtin("preview");
        assert!(p.set("spp", "0").is_err());
        assert!(p.set("strategy", "magic").is_err());
        assert!(p.set("nope", "1").is_err());
        p.set("strategy", "sobol").unwrap();
        assert_eq!(p.light_strategy, Strategy::Sobol);
    }

    #[test]
    fn overrides_are_validated_together_after_the_last() {
        let mut p = Profile::builtin("final");
        (p.max_depth, p.diffuse_depth) = (6, 4);
        // One at a time, max_depth = 0 is below diffuse_depth; together with it, valid.
        assert!(p.clone().set("max_depth", "0").is_err());
        p.set_all([("max_depth", "0"), ("diffuse_depth", "0")]).unwrap();
        assert_eq!((p.max_depth, p.diffuse_depth), (0, 0));
        // Invalid at the end: an error naming the field, and the profile unchanged.
        let before = p.clone();
        let e = p.set_all([("spp", "8"), ("diffuse_depth", "3")]).unwrap_err();
        assert!(e.starts_with("diffuse_depth"), "{e}");
        assert_eq!(p.spp, before.spp);
        assert!(p.set_all([("spp", "x")]).unwrap_err().contains("spp"));
    }

    #[test]
    fn split_with_zero_cutoff_is_invalid_roulette_is_not() {
        let mut p = Profile::builtin("final");
        assert_eq!(p.branching, Branching::Split);
        let e = p.clone().set("throughput_cutoff", "0").unwrap_err();
        assert!(e.starts_with("throughput_cutoff: with branching = \"split\""), "{e}");
        p.set_all([("throughput_cutoff", "0"), ("branching", "roulette")]).unwrap();
        assert!(p.set("branching", "split").is_err());
        assert!(Profile::builtin("final").set("throughput_cutoff", "-0").is_err());
        // A value below 1 that rounds to 1 in f32 says so.
        let e = Profile::builtin("final").set("throughput_cutoff", "0.99999999999").unwrap_err();
        assert!(e.contains("got 1 (as an f32"), "{e}");
        p.set("throughput_cutoff", "1e-9").unwrap();
        p.set("branching", "split").unwrap();
    }

    #[test]
    fn a_single_strategy_refines_the_general_one_in_either_order() {
        for pairs in [[("pixel_strategy", "random"), ("strategy", "grid")], [("strategy", "grid"), ("pixel_strategy", "random")]] {
            let mut p = Profile::builtin("preview");
            p.set_all(pairs).unwrap();
            assert_eq!((p.pixel_strategy, p.light_strategy, p.wavelength_strategy), (Strategy::Random, Strategy::Grid, Strategy::Grid));
        }
    }

    #[test]
    fn names_are_exact_and_lowercase() {
        let mut p = Profile::builtin("preview");
        for (k, v) in
            [("light_strategy", "GRID"), ("strategy", "Sobol"), ("filter", "TENT"), ("branching", "Split"), ("light_selection", "Local")]
        {
            let e = p.set(k, v).unwrap_err();
            assert!(e.starts_with(k) && e.contains(&format!("`{v}`")) && e.contains("names are lowercase"), "{e}");
        }
        assert!(!p.set("filter", "mitchell").unwrap_err().contains("lowercase"));
        p.set_all([("light_strategy", "centre"), ("filter", "tent"), ("branching", "split")]).unwrap();
        assert_eq!((p.light_strategy, p.filter, p.branching), (Strategy::Center, Filter::Tent, Branching::Split));
    }

    #[test]
    fn light_selection_parses_and_leaves_the_film_record_of_all_unchanged() {
        let mut p = Profile::builtin("final");
        assert_eq!(p.light_selection, LightSelection::All);
        let before = serde_json::to_string(&p).unwrap();
        assert!(!before.contains("light_selection"), "`all` is left out of the record: films of older renders still resume");
        for mode in LightSelection::ALL {
            p.set("light_selection", mode.name()).unwrap();
            assert_eq!(p.light_selection, mode);
        }
        assert!(serde_json::to_string(&p).unwrap().contains("\"light_selection\":\"tree\""));
        let e = p.set("light_selection", "nearest").unwrap_err();
        assert!(e.contains("expected all, uniform, power, local or tree"), "{e}");
        // In a file: the field and its line.
        let text = "spp = 4\npixel_strategy = \"jittered\"\nlight_samples = 1\nlight_strategy = \"jittered\"\nmax_depth = 2\nlight_selection = \"near\"\n";
        let e = Profile::parse(Path::new("p.toml"), text).unwrap_err().to_string();
        assert!(e.contains("p.toml") && e.contains(":6") && e.contains("light_selection"), "{e}");
        let ok = text.replace("\"near\"", "\"power\"");
        assert_eq!(Profile::parse(Path::new("p.toml"), &ok).unwrap().light_selection, LightSelection::Power);
    }
}
