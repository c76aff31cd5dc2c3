//! The speed/accuracy study (`strata study`): render a scene at a series of sample counts with several
//! strategies and seeds, compare each render with a reference, and report samples, seconds, rays, MSE,
//! relMSE and efficiency = 1 / (MSE x seconds), as a table, a CSV, a log-log plot and a contact sheet.
//!
//! ```text
//! reference (EXR file | cached high-sample render | analytic)
//!      |
//! run::run_series   for strategy, count, seed: configure the profile, render, metrics
//!      |
//! run::summarize    mean over seeds; fitted log-log slopes (metrics::fit_loglog)
//!      v
//! table (stdout), csv::write, plot::write (study.png), sheet::write (sheet.png)
//! ```
//!
//! How a sample count maps onto the integrals is [`run::configure`]'s doc.

pub mod analytic;
pub mod csv;
pub mod metrics;
pub mod plot;
pub mod reference;
pub mod run;
pub mod sheet;

/// The integrals of distribution ray tracing a study can vary.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Integral {
    Pixel,
    Light,
    Lens,
    Time,
    Glossy,
}

impl Integral {
    pub const ALL: [Integral; 5] = [Integral::Pixel, Integral::Light, Integral::Lens, Integral::Time, Integral::Glossy];

    pub fn name(self) -> &'static str {
        match self {
            Integral::Pixel => "pixel",
            Integral::Light => "light",
            Integral::Lens => "lens",
            Integral::Time => "time",
            Integral::Glossy => "glossy",
        }
    }

    pub fn parse(s: &str) -> Option<Integral> {
        Integral::ALL.into_iter().find(|i| i.name().eq_ignore_ascii_case(s))
    }
}

/// A set of integrals (no duplicates, in [`Integral::ALL`] order).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct IntegralSet(u8);

impl IntegralSet {
    pub fn all() -> IntegralSet {
        IntegralSet::of(&Integral::ALL)
    }

    pub fn of(list: &[Integral]) -> IntegralSet {
        IntegralSet(list.iter().fold(0, |m, i| m | 1 << *i as u8))
    }

    pub fn contains(&self, i: Integral) -> bool {
        self.0 & (1 << i as u8) != 0
    }

    pub fn len(&self) -> usize {
        self.0.count_ones() as usize
    }

    pub fn is_empty(&self) -> bool {
        self.0 == 0
    }

    pub fn iter(&self) -> impl Iterator<Item = Integral> + '_ {
        Integral::ALL.into_iter().filter(|i| self.contains(*i))
    }

    /// `"all"` or a comma-separated list of integral names.
    pub fn parse(s: &str) -> Result<IntegralSet, String> {
        if s.trim().eq_ignore_ascii_case("all") {
            return Ok(IntegralSet::all());
        }
        if s.split(',').all(|p| p.trim().is_empty()) {
            return Err("the list of integrals is empty".into());
        }
        // (As the other lists of `study`: no empty item, no item twice, `all` alone.)
        let mut list = Vec::new();
        for part in s.split(',').map(str::trim) {
            if part.is_empty() {
                return Err(format!("`{s}`: an empty item"));
            }
            if part.eq_ignore_ascii_case("all") {
                return Err(format!("`{s}`: `all` (every integral) stands alone, not in a list"));
            }
            let i = Integral::parse(part).ok_or_else(|| {
                let all: Vec<_> = Integral::ALL.iter().map(|i| i.name()).collect();
                format!("unknown integral `{part}` (one of {}, or all)", all.join(", "))
            })?;
            if list.contains(&i) {
                return Err(format!("`{s}`: `{part}` is listed twice"));
            }
            list.push(i);
        }
        Ok(IntegralSet::of(&list))
    }

    pub fn names(&self) -> String {
        self.iter().map(|i| i.name()).collect::<Vec<_>>().join(",")
    }
}
