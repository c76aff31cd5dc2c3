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

    /// [`Integral::parse`], or why not (the names it knows).
    pub fn parse_or_explain(s: &str) -> Result<Integral, String> {
        Integral::parse(s).ok_or_else(|| {
            let all: Vec<_> = Integral::ALL.iter().map(|i| i.name()).collect();
            format!("unknown integral `{s}` (one of {}, or all)", all.join(", "))
        })
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

    pub fn names(&self) -> String {
        self.iter().map(|i| i.name()).collect::<Vec<_>>().join(",")
    }
}
