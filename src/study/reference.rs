//! The reference image a study measures against: a given EXR, a high-sample render (rendered once and
//! cached), or the analytic image of a Lambert plane under a quad light.
//!
//! The reference is the converged value of the *same* estimator the series runs: the studied integrals
//! sampled, the others held at their centre sample ([`reference_profile`]: [`configure`] with the jittered
//! strategy and `N` samples, or the analytic image with the matching footprint and light).
//!
//! Cache: `DIR/reference-<key>.exr` with a sidecar `reference-<key>.txt` holding the full key text (crate
//! version, the executable's hash, scene hash and size, seed, N, the complete reference profile) and the hash of the image written
//! with it. A cached file is reused only if the sidecar's key equals the current key exactly, the image
//! is the one written (not replaced since) and has the scene's size; any change to
//! the scene file, profile, mapping or N gives a different key (and so a fresh render).

use super::analytic::{Footprint, QuadIrradiance};
use super::run::{configure, light_only, render_units, Plan, REFERENCE_SEED};
use super::{Integral, IntegralSet};
use crate::film::file::{build_id, read_film, write_film, FilmHeader};
use crate::film::output::{read_image, write_atomic, write_image_with, Provenance};
use crate::film::Film;
use crate::render::{RenderJob, TILE};
use crate::sample::Strategy;
use crate::scene::{Profile, Scene};
use crate::wavefront::Settings;
use glam::DVec3;
use std::path::{Path, PathBuf};

/// Where the reference comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum ReferenceSource {
    File(PathBuf),
    Samples(u32),
    Analytic,
}

/// A reference image and a one-line description of where it came from.
pub struct Reference {
    pub image: Vec<DVec3>,
    pub description: String,
    /// Warnings about the reference (a file rendered with another estimator than the study's).
    pub warnings: Vec<String>,
}

/// Errors: `Input` for bad requests (exit 2), `Runtime` for failures while working (exit 1),
/// `Interrupted` when the plan's cancel flag stopped the reference render (nothing is cached; the text
/// says where its finished work units were kept, if any).
#[derive(Debug)]
pub enum RefError {
    Input(String),
    Runtime(String),
    Interrupted(String),
}

/// Obtain the reference for a study `plan` on `scene` with the base `profile`.
/// `progress` is told the rendered reference's work units done and total as they finish.
pub fn obtain(
    source: &ReferenceSource,
    scene: &Scene,
    profile: &Profile,
    plan: &Plan,
    out_dir: &Path,
    progress: Option<&(dyn Fn(usize, usize) + Sync)>,
) -> Result<Reference, RefError> {
    match source {
        ReferenceSource::File(path) => from_file(path, scene, profile, plan),
        ReferenceSource::Analytic => analytic(scene, profile, &plan.integrals).map_err(RefError::Input),
        ReferenceSource::Samples(n) => rendered(scene, profile, plan, *n, out_dir, progress),
    }
}

/// The profile of the rendered reference: [`configure`] with the jittered strategy and `n` samples.
///
/// With `--light-samples-from-spp` (a run of count m takes m spp x m light samples) the reference takes
/// `n` spp x m light samples, m the largest count: it has `n / m` times the largest run's camera samples
/// *and* light samples per pixel. (With the profile's light samples, a reference of 16 m spp would have
/// no more light samples per pixel than the largest run, and its own light noise would be measured.)
pub fn reference_profile(base: &Profile, plan: &Plan, n: u32) -> Result<Profile, String> {
    let mut p = configure(base, &plan.integrals, Strategy::Jittered, n, false)?;
    if plan.light_from_spp && plan.integrals.contains(Integral::Light) && !light_only(&plan.integrals) {
        let largest = plan.counts.iter().copied().max().unwrap_or(1);
        p.light_samples = largest;
        p.validate().map_err(|(f, m)| format!("{f}: {m}"))?;
    }
    Ok(p)
}

/// How the estimator a reference file records (`file`, its provenance's profile) differs from the
/// study's (`study`, the profile its reference would be rendered with): what changes the converged image
/// (the filter, an integral sampled in one and held at its centre in the other, shadows through glass, a
/// shallower depth), each with the `--set` that mends it where one does. A deeper reference is no
/// difference: it is closer to the light transport's solution, and the MSE then counts the runs' own
/// truncation (a shallow profile's real cost). Strategies, counts, branching and light selection change
/// only the noise, and are not compared.
pub fn estimator_differences(scene: &Scene, file: &Profile, study: &Profile) -> Vec<(String, Option<String>)> {
    let mut out = Vec::new();
    let held = |s: Strategy| s == Strategy::Center;
    let f = &scene.features;
    let bounces = file.diffuse_depth.min(study.diffuse_depth) > 0;
    // (Integrals the scene does not exercise: held or sampled, the image is the same.)
    let dims = [
        ("pixel", true, file.pixel_strategy, study.pixel_strategy),
        ("lens", f.lens, file.lens_strategy, study.lens_strategy),
        ("time", f.motion, file.time_strategy, study.time_strategy),
        ("glossy", f.glossy, file.glossy_strategy, study.glossy_strategy),
        ("light", f.area_lights, file.light_strategy, study.light_strategy),
        ("diffuse bounce", bounces, file.diffuse_strategy, study.diffuse_strategy),
        ("wavelength", f.dispersion, file.wavelength_strategy, study.wavelength_strategy),
    ];
    for (name, _, f, s) in dims.into_iter().filter(|d| d.1) {
        if held(f) != held(s) {
            let how = |x: Strategy| if held(x) { "held at its centre".to_string() } else { format!("sampled ({x})") };
            out.push((format!("the {name} integral is {} in the reference, {} in the study", how(f), how(s)), None));
        }
    }
    if !held(file.pixel_strategy) && !held(study.pixel_strategy) && file.filter != study.filter {
        let (f, s) = (file.filter.name(), study.filter.name());
        out.push((format!("filter {f} in the reference, {s} in the study"), Some(format!("filter={s}"))));
    }
    // (The depth changes nothing in a scene without mirrors, glass, glossy surfaces or diffuse bounces.)
    let deep = f.mirror || f.dielectric || f.glossy || file.diffuse_depth.max(study.diffuse_depth) > 0;
    let depths = [("max_depth", file.max_depth, study.max_depth, deep), ("diffuse_depth", file.diffuse_depth, study.diffuse_depth, true)];
    for (what, f, s, _) in depths.into_iter().filter(|d| d.3) {
        if f < s {
            out.push((format!("{what} {f} in the reference, {s} in the study"), Some(format!("{what}={s}"))));
        }
    }
    if file.transmissive_shadows != study.transmissive_shadows {
        let (f, s) = (file.transmissive_shadows, study.transmissive_shadows);
        out.push((format!("transmissive_shadows {f} in the reference, {s} in the study"), Some(format!("transmissive_shadows={s}"))));
    }
    out
}

/// The warnings for a reference file rendered with `provenance` (None: the file records none) when the
/// study renders `study` on `scene`.
fn provenance_warnings(path: &Path, provenance: Option<&Provenance>, scene: &Scene, study: &Profile) -> Vec<String> {
    let Some(p) = provenance else {
        return vec![format!(
            "note: {} records no Strata settings (another renderer's image, or one written before session 41): make sure \
             it was rendered with the studied filter ({}), depths and integrals, or the MSE measures that difference too",
            path.display(),
            study.filter.name()
        )];
    };
    let mut out = Vec::new();
    if !p.complete {
        out.push(format!(
            "warning: {} is an incomplete render (interrupted, or merged with gaps): its unfinished work units' pixels \
             hold fewer samples or none, and the MSE measures them",
            path.display()
        ));
    }
    if p.scene_hash != scene.hash {
        out.push(format!(
            "warning: {} was rendered from another scene file, or from this one before an edit (scene hash {:016x}, now {:016x})",
            path.display(),
            p.scene_hash,
            scene.hash
        ));
    }
    match serde_json::from_str::<Profile>(&p.profile) {
        Ok(file) => {
            let d = estimator_differences(scene, &file, study);
            if !d.is_empty() {
                let what: Vec<&str> = d.iter().map(|(w, _)| w.as_str()).collect();
                let sets: Vec<String> = d.iter().filter_map(|(_, s)| s.as_ref().map(|s| format!("--set {s}"))).collect();
                let mend =
                    if sets.len() == d.len() { format!(" render the reference again with {}, or", sets.join(" ")) } else { String::new() };
                out.push(format!(
                    "warning: {} estimates another image than the study's runs: {}. The MSE measures that difference as well \
                     as the runs' error, and may rank profiles wrongly:{mend} let the study render its own (--reference-spp N)",
                    path.display(),
                    what.join("; "),
                ));
            }
        }
        Err(e) => out.push(format!("warning: {}: its recorded profile cannot be read ({e}): not compared", path.display())),
    }
    out
}

fn from_file(path: &Path, scene: &Scene, profile: &Profile, plan: &Plan) -> Result<Reference, RefError> {
    let is_exr = path.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    if !is_exr {
        return Err(RefError::Input(format!("{}: the reference must be a linear .exr image", path.display())));
    }
    let (w, h, px) = read_image(path).map_err(RefError::Input)?;
    if (w, h) != (scene.width, scene.height) {
        return Err(RefError::Input(format!(
            "{}: reference is {w}x{h} but the scene renders {}x{}",
            path.display(),
            scene.width,
            scene.height
        )));
    }
    let largest = plan.counts.iter().copied().max().unwrap_or(1);
    let study = reference_profile(profile, plan, largest).map_err(RefError::Input)?;
    let warnings = match Provenance::read(path) {
        Ok(provenance) => provenance_warnings(path, provenance.as_ref(), scene, &study),
        Err(e) => vec![format!("warning: {e}: how the reference was rendered cannot be read, so it is not compared with the study")],
    };
    let image = px.iter().map(|c| c.as_dvec3()).collect();
    Ok(Reference { image, description: format!("file {}", path.display()), warnings })
}

/// The analytic image for the studied integrals (see [`QuadIrradiance`]).
pub fn analytic(scene: &Scene, profile: &Profile, integrals: &IntegralSet) -> Result<Reference, String> {
    let form = QuadIrradiance::from_scene(scene, profile)?;
    let pixel_sampled = integrals.contains(Integral::Pixel) && !light_only(integrals);
    let footprint = if pixel_sampled { Footprint::Filter(profile.filter) } else { Footprint::Centre };
    let light_centre = !integrals.contains(Integral::Light);
    let image = form.with_light_at_centre(light_centre).image(footprint);
    let what = match footprint {
        Footprint::Centre => "at pixel centres".to_string(),
        Footprint::Filter(f) => format!("over the {f} filter footprint (Gauss-Legendre)"),
    };
    let light = if light_centre { "light held at its centre" } else { "Lambert's polygon formula" };
    Ok(Reference { image, description: format!("analytic ({light}, {what}, f64)"), warnings: Vec::new() })
}

/// The full text the cache is keyed by.
pub fn cache_key_text(scene: &Scene, reference_profile: &Profile) -> String {
    let profile = serde_json::to_string(reference_profile).expect("profiles serialise");
    format!(
        "strata study reference v2\ncrate {}\nrenderer {}\nscene {:016x} {}x{}\nseed {REFERENCE_SEED}\nprofile {profile}\n",
        env!("CARGO_PKG_VERSION"),
        renderer_id(),
        scene.hash,
        scene.width,
        scene.height
    )
}

/// The running executable's hash ([`build_id`]), as the cache key's `renderer` line: a reference rendered
/// by another build (pulled changes, a local edit) is not reused, which the crate version (0.1.0 at every
/// commit) could not tell. An executable that cannot be read gives a line that matches no other run.
fn renderer_id() -> String {
    static ID: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    ID.get_or_init(|| match build_id() {
        0 => {
            errln!("note: cannot read the strata executable to key the reference cache: the reference is rendered afresh");
            let now = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos());
            format!("unreadable: process {} at {now}", std::process::id())
        }
        id => format!("{id:016x}"),
    })
    .clone()
}

/// The sidecar's text: the cache key, then the FNV-1a hash of the image's f32 bits.
fn with_image_hash(key: &str, px: &[glam::Vec3]) -> String {
    let h = crate::sample::hash::fnv1a(px.iter().flat_map(|c| c.to_array()).flat_map(|x| x.to_bits().to_le_bytes()));
    format!("{key}image {h:016x}\n")
}

/// FNV-1a of the key text (file name only; the sidecar holds the full text that is compared).
fn key_hash(text: &str) -> u64 {
    crate::sample::hash::fnv1a(text.bytes())
}

/// Paths of the cached reference and its sidecar for `key_text`.
pub fn cache_paths(out_dir: &Path, key_text: &str) -> (PathBuf, PathBuf) {
    let stem = format!("reference-{:016x}", key_hash(key_text));
    (out_dir.join(format!("{stem}.exr")), out_dir.join(format!("{stem}.txt")))
}

fn rendered(
    scene: &Scene,
    profile: &Profile,
    plan: &Plan,
    n: u32,
    out_dir: &Path,
    progress: Option<&(dyn Fn(usize, usize) + Sync)>,
) -> Result<Reference, RefError> {
    let ref_profile = reference_profile(profile, plan, n).map_err(|e| RefError::Input(format!("--reference-spp: {e}")))?;
    let key = cache_key_text(scene, &ref_profile);
    let (exr, txt) = cache_paths(out_dir, &key);
    let what = if light_only(&plan.integrals) {
        "light samples".to_string()
    } else if ref_profile.light_samples > 1 && plan.integrals.contains(Integral::Light) {
        format!("samples per pixel x {} light samples", ref_profile.light_samples)
    } else {
        "samples per pixel".to_string()
    };
    if let (Ok(side), Ok((w, h, px))) = (std::fs::read_to_string(&txt), read_image(&exr)) {
        // The sidecar holds the key and the hash of the image written with it: an image replaced since
        // (another reference of the same size copied over it) is not served.
        if side == with_image_hash(&key, &px) && (w, h) == (scene.width, scene.height) {
            {
                let description = format!("jittered, {n} {what}, reused cached {}", exr.display());
                return Ok(Reference { image: px.iter().map(|c| c.as_dvec3()).collect(), description, warnings: Vec::new() });
            }
        }
    }
    // Resumable: an interrupted reference keeps its finished work units in a film beside the cache
    // (`reference-<key>.film`, named by the same key), which the same study continues.
    let partial = exr.with_extension("film");
    // Stamped with this build (which the cache key names anyway): a partial film of another build is
    // not continued.
    let fresh = FilmHeader::fresh(scene, &ref_profile, 0..ref_profile.spp, TILE, REFERENCE_SEED);
    let header = fresh.stamped(fresh.completed.clone(), false);
    let n_units = header.completed.len();
    // A partial film that cannot be continued is said so at once, before the reference's wait (a user
    // trial: one flipped byte, and the study rendered the reference from the start without a word
    // after promising to continue it).
    let (film, completed) = match read_film(&partial) {
        Ok(f) if f.header == FilmHeader { completed: f.header.completed.clone(), ..header.clone() } => (f.film, f.header.completed),
        other => {
            if partial.exists() {
                let why = match other {
                    Err(e) => e,
                    Ok(_) => "it is not of this reference and build".to_string(),
                };
                errln!(
                    "warning: the interrupted reference's film {} cannot be continued ({why}): the reference is rendered from the start",
                    partial.display()
                );
            }
            (Film::new(scene.width, scene.height), header.completed.clone())
        }
    };
    let resumed = completed.iter().filter(|&&c| c).count();
    let mut job = RenderJob::new(scene, Settings { profile: ref_profile.clone(), seed: REFERENCE_SEED });
    job.threads = plan.threads;
    job.cancel = plan.cancel.as_deref();
    job.progress = progress;
    let (film, completed, stats) = render_units(&job, film, completed).map_err(RefError::Runtime)?;
    if !stats.completed {
        let done = completed.iter().filter(|&&c| c).count();
        if done == resumed {
            return Err(RefError::Interrupted(String::new()));
        }
        write_film(&partial, &FilmHeader { completed, ..header }, &film).map_err(RefError::Runtime)?;
        return Err(RefError::Interrupted(format!(
            "; the reference's {done} of {n_units} work units are kept in {}: the same study continues it",
            partial.display()
        )));
    }
    let seconds = stats.seconds + stats.selection_seconds;
    let resumed_note = if resumed > 0 { format!(", resumed from {resumed} of {n_units} work units") } else { String::new() };
    let rgb = film.to_rgb();
    // The image first, then the sidecar: an interrupted write leaves no sidecar, so no stale reuse.
    let _ = std::fs::remove_file(&txt);
    let provenance = Provenance::of(&FilmHeader { completed, ..header });
    write_image_with(&exr, scene.width, scene.height, &rgb, Some(&provenance)).map_err(RefError::Runtime)?;
    // (Hashed as read back, as a later study reads it.)
    let (_, _, written) = read_image(&exr).map_err(RefError::Runtime)?;
    let side = with_image_hash(&key, &written);
    write_atomic(&txt, |tmp| std::fs::write(tmp, &side).map_err(|e| e.to_string())).map_err(RefError::Runtime)?;
    let _ = std::fs::remove_file(&partial);
    let description = format!("jittered, {n} {what}, rendered in {seconds:.2} s{resumed_note}, cached as {}", exr.display());
    Ok(Reference { image: rgb.iter().map(|c| c.as_dvec3()).collect(), description, warnings: Vec::new() })
}
