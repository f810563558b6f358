//! Whether a run stays where its model is defined: the moving points on a beam that refuses
//! leaving it stay inside it, and every profile under an element covers the positions the
//! element reads, `x0 + v t + offset` (m) from the moment the profiles come on
//! ([`RunConfig::profile_on`]) to the end of the run.
//!
//! Checked per sample before a run, on the profiles given (`check_coverage`: the engine and
//! [`crate::Excitations`]), and before any profile exists, in a pipeline's check mode, over
//! the whole box of sampling ranges ([`check_profile_starts`]). A generated profile covers
//! `[GENERATED_PROFILE_START, length)` (from `x = 0`), its length a control of the stage that
//! makes it; what the box check can refuse is a point reading a generated profile before its
//! start (`x0 < 0` under a generated profile).

use crate::config::RunConfig;
use crate::corners::{corner_values, largest_corners};
use crate::profile::ProfileSource;
use crate::{Error, Result};
use mbd_system::model::{Model, ModelEnd};
use mbd_system::schema::Outside;
use mbd_system::system::{Profile as DescribedProfile, GENERATED_PROFILE_START};
use mbd_system::{System, SystemSource};

/// Checks that the run stays where the model is defined: the moving points on a beam that
/// refuses leaving it stay strictly inside it for the whole run, and every sampled profile
/// covers the positions its elements read from the moment the profile comes on
/// ([`RunConfig::profile_on`]) to the end of the run. Positions in m along the track, a point
/// at `x0 + speed t + offset`.
pub(crate) fn check_coverage(
    system: &System,
    model: &Model,
    c: &RunConfig,
    sources: &[ProfileSource],
) -> Result<()> {
    let (t_end, speed) = (c.t_end(), model.speed);
    for (b, beam) in model.beams.iter().enumerate() {
        let offsets = || {
            model
                .points
                .iter()
                .filter(move |p| p.0 == Some(b))
                .map(|p| p.1)
        };
        if beam.outside != Outside::Refuse || offsets().next().is_none() {
            continue;
        }
        let lo = offsets().map(|o| c.x0 + o).fold(f64::INFINITY, f64::min);
        let hi = offsets()
            .map(|o| c.x0 + speed * t_end + o)
            .fold(f64::NEG_INFINITY, f64::max);
        let length = beam.length;
        if !(lo > 0.0 && hi < length) {
            return Err(Error::TooShort {
                what: format!("beam `{}` (length {length} m)", system.beams[b].name),
                have_lo: 0.0,
                have_hi: length,
                need_lo: lo,
                need_hi: hi,
                hint: "lengthen the beam, shorten the run (duration) or move x0; or let points leave it (`outside: rigid`)".to_owned(),
            });
        }
    }
    check_profile_coverage(system, model, c, sources)
}

/// Where an element reads its profile in a run.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Read {
    /// The element.
    element: usize,
    /// Its profile.
    profile: usize,
    /// The moving point it rests on.
    point: usize,
    /// The positions read (m): the point's from the moment the profiles come on to the end.
    x: [f64; 2],
}

/// The reads of `model`'s elements under a profile in run `c`, in element order (none when
/// the profiles never come on).
fn profile_reads(model: &Model, c: &RunConfig) -> Vec<Read> {
    let (t_end, t_on) = (c.t_end(), c.profile_on());
    if t_on > t_end {
        return Vec::new();
    }
    let at = |t: f64, offset: f64| c.x0 + model.speed * t + offset;
    model
        .elements
        .iter()
        .enumerate()
        .filter_map(|(e, el)| match (el.profile, el.to) {
            (Some(p), ModelEnd::Moving(pt)) => {
                let offset = model.points[pt].1;
                Some(Read {
                    element: e,
                    profile: p,
                    point: pt,
                    x: [at(t_on, offset), at(t_end, offset)],
                })
            }
            _ => None,
        })
        .collect()
}

/// The first of `reads` that its profile does not cover, with what that profile covers:
/// `covered(p)` is the range of profile `p` (m), `None` for one that covers every `x`.
fn uncovered(
    reads: &[Read],
    covered: impl Fn(usize) -> Option<[f64; 2]>,
) -> Option<(usize, [f64; 2])> {
    reads.iter().enumerate().find_map(|(k, r)| {
        let have = covered(r.profile)?;
        (r.x[0] < have[0] || r.x[1] > have[1]).then_some((k, have))
    })
}

/// Checks that every sampled profile covers the positions its elements read from the moment
/// the profile comes on ([`RunConfig::profile_on`]) to the end of the run.
fn check_profile_coverage(
    system: &System,
    model: &Model,
    c: &RunConfig,
    sources: &[ProfileSource],
) -> Result<()> {
    let reads = profile_reads(model, c);
    let Some((k, have)) = uncovered(&reads, |p| sources[p].covered()) else {
        return Ok(());
    };
    let r = reads[k];
    Err(Error::TooShort {
        what: format!(
            "profile `{}` under element `{}`",
            system.profiles[r.profile].name(),
            system.elements[r.element].name
        ),
        have_lo: have[0],
        have_hi: have[1],
        need_lo: r.x[0],
        need_hi: r.x[1],
        hint: "generate profiles that cover the whole run plus the vehicle length".to_owned(),
    })
}

/// An element reading a generated profile before its start: what
/// [`check_profile_starts`] refuses ([`Error::BeforeProfile`]).
#[derive(Debug, Clone, PartialEq)]
pub struct EarlyRead {
    /// The profile.
    pub profile: String,
    /// The element reading it.
    pub element: String,
    /// The element's moving point.
    pub point: String,
    /// The run's start position of the frame (m).
    pub x0: f64,
    /// The least position read (m, to the millimetre).
    pub read: f64,
    /// The point's position relative to `x0` when it reads there (m, to the millimetre).
    pub travel: f64,
    /// When and at which sampled values it reads there (empty, or text from `, `/` when`).
    pub when: String,
    /// The least `x0` that passes (m, rounded up to the millimetre).
    pub least_x0: f64,
}

impl std::fmt::Display for EarlyRead {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "x0 = {} m: the generated profile `{}` covers [{GENERATED_PROFILE_START}, length) but element `{}` reads it from x = {} m (its point `{}` at x0 {:+} m{}); set x0 >= {} m, or make `{}` a harmonic profile (it covers every x)",
            self.x0, self.profile, self.element, self.read, self.point, self.travel, self.when, self.least_x0, self.profile
        )
    }
}

/// Refuses a run whose moving points read a generated profile before its start
/// ([`GENERATED_PROFILE_START`]) anywhere in the box of sampling ranges, the check a pipeline
/// makes before any profile exists: the positions read, `x0 + v t + offset` with the speed and
/// the offsets expressions of the sampled parameters, are taken at the corners of the box
/// (every corner, or the searched least one: [`crate::corners`], as for the time-step bound),
/// and the least position each element reads is checked with the per-sample check's own
/// comparison. The error
/// ([`Error::BeforeProfile`]) gives the least `x0` that passes and the corner that reads
/// least. A corner out of the description's domains is refused as a sample would be.
pub fn check_profile_starts(system: &System, c: &RunConfig) -> Result<()> {
    c.validate()?;
    // A combination reads its generated parts.
    let generated = |p: usize| {
        let is_generated =
            |p: usize| matches!(system.profiles[p], DescribedProfile::Generated { .. });
        let any = match &system.profiles[p] {
            DescribedProfile::Combination { terms, .. } => terms.iter().any(|t| is_generated(t.0)),
            _ => is_generated(p),
        };
        any.then_some([GENERATED_PROFILE_START, f64::INFINITY])
    };
    if !system
        .elements
        .iter()
        .any(|e| e.profile.is_some_and(|p| generated(p).is_some()))
    {
        return Ok(());
    }
    let ranges = system.ranges();
    let reads_at = |mask: u64| -> Result<Vec<Read>> {
        let model = system.instantiate(&corner_values(system, &ranges, mask))?;
        Ok(profile_reads(&model, c))
    };
    // Per element, the corner whose read starts least.
    let least: Vec<(Read, u64)> = largest_corners(ranges.len(), |mask| {
        Ok(reads_at(mask)?.iter().map(|r| -r.x[0]).collect())
    })?
    .iter()
    .enumerate()
    .map(|(k, &(_, mask))| Ok((reads_at(mask)?[k], mask)))
    .collect::<Result<_>>()?;
    let reads: Vec<Read> = least.iter().map(|l| l.0).collect();
    let Some((k, have)) = uncovered(&reads, generated) else {
        return Ok(());
    };
    let (r, mask) = least[k];
    // The sampled parameters the position read depends on, at the corner that reads least.
    let mut roots = system.points[r.point].offset.parameters();
    if c.profile_on() > 0.0 {
        roots.extend(system.speed.parameters());
    }
    let corner = corner_values(system, &ranges, mask);
    let at: Vec<String> = system
        .sampled_sources(roots)
        .iter()
        .filter_map(|n| Some(format!("{n} = {}", corner.get(n)?)))
        .collect();
    let mut when = String::new();
    if c.profile_on() > 0.0 {
        when += &format!(" when the profiles come on, t = {} s", c.profile_on());
    }
    if !at.is_empty() {
        when += &format!(", over the sampling ranges least at {}", at.join(", "));
    }
    let travel = r.x[0] - c.x0;
    Err(Error::BeforeProfile(Box::new(EarlyRead {
        profile: system.profiles[r.profile].name().to_owned(),
        element: system.elements[r.element].name.clone(),
        point: system.points[r.point].name.clone(),
        x0: c.x0,
        read: millimetres(r.x[0]),
        travel: millimetres(travel),
        when,
        // Rounded up to the millimetre: the value given passes.
        least_x0: ((have[0] - travel) * 1e3).ceil() / 1e3 + 0.0,
    })))
}

/// The farthest position (m) an element reads a generated profile at in run `c`, over the box
/// of sampling ranges (its corners, as [`check_profile_starts`] takes them):
/// what a generated profile must reach to cover the run of every design inside the ranges;
/// `None` when no element reads a generated profile (or the profiles never come on).
pub fn generated_profile_reach(system: &System, c: &RunConfig) -> Result<Option<f64>> {
    c.validate()?;
    let generated = |p: usize| matches!(system.profiles[p], DescribedProfile::Generated { .. });
    let ranges = system.ranges();
    let reach = largest_corners(ranges.len(), |mask| {
        let model = system.instantiate(&corner_values(system, &ranges, mask))?;
        Ok(profile_reads(&model, c)
            .iter()
            .filter(|r| generated(r.profile))
            .map(|r| r.x[1])
            .collect())
    })?;
    Ok(reach.into_iter().map(|r| r.0).reduce(f64::max))
}

/// [`check_profile_starts`] as a pipeline's check mode reports it: its refusal placed at the
/// profile's line in the description `source` (which `system` compiles),
/// `file:line:col: profiles.NAME: x0 = ...` ([`Error::Described`]); other errors unchanged.
pub fn check_profile_starts_described(
    source: &SystemSource,
    system: &System,
    c: &RunConfig,
) -> Result<()> {
    check_profile_starts(system, c).map_err(|e| match &e {
        Error::BeforeProfile(early) => {
            let at = format!("profiles.{}", early.profile);
            Error::Described(source.problem_at(&at, format!("{at}: {e}")))
        }
        _ => e,
    })
}

/// `x` (m) rounded to the millimetre, for messages (`-0` shown as `0`).
fn millimetres(x: f64) -> f64 {
    (x * 1e3).round() / 1e3 + 0.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::StartMode;
    use mbd_system::Override;
    use std::collections::BTreeMap;

    const QUARTER_CAR: &str = include_str!("../../../systems/quarter-car.yaml");

    fn compile(text: &str) -> System {
        mbd_system::load_str(text, "car.yaml", &BTreeMap::new()).unwrap_or_else(|d| panic!("{d}"))
    }

    /// A 2 s run from `x0` with the profiles off for the first `zero` of it.
    fn run(x0: f64, zero: f64) -> RunConfig {
        RunConfig {
            duration: 2.0,
            dt: 1e-4,
            output_every: 10,
            start: StartMode::Equilibrium,
            startup_zero_fraction: zero,
            startup_ramp_fraction: 0.0,
            x0,
        }
    }

    /// `x0 < 0` under a generated profile is refused before any profile exists, with the least
    /// `x0` that passes, and that `x0` does pass.
    #[test]
    fn a_start_before_a_generated_profile_is_refused() {
        let system = compile(QUARTER_CAR);
        let e = check_profile_starts(&system, &run(-20.0, 0.0)).unwrap_err();
        let Error::BeforeProfile(early) = &e else {
            panic!("{e}");
        };
        assert_eq!(
            (
                early.profile.as_str(),
                early.element.as_str(),
                early.point.as_str()
            ),
            ("road", "tyre", "road")
        );
        assert_eq!((early.read, early.least_x0), (-20.0, 0.0));
        let text = e.to_string();
        assert!(
            text.starts_with("x0 = -20 m: the generated profile `road` covers [0, length)"),
            "{text}"
        );
        assert!(text.contains("set x0 >= 0 m"), "{text}");
        for x0 in [0.0, 5.0] {
            check_profile_starts(&system, &run(x0, 0.0)).unwrap();
        }
        assert!(check_profile_starts(&system, &run(-1e-3, 0.0)).is_err());
    }

    /// A generated profile must reach the farthest point read over the sampling box: the
    /// quarter car's tyre at the fastest speed (108 km/h = 30 m/s) at the run's last stored
    /// time, from x0 = 5 m.
    #[test]
    fn the_reach_of_a_generated_profile_is_the_fastest_corners_last_read() {
        let system = compile(QUARTER_CAR);
        let c = run(5.0, 0.25);
        let reach = generated_profile_reach(&system, &c).unwrap();
        let want = 5.0 + 30.0 * c.t_end();
        assert!(reach.is_some_and(|r| (r - want).abs() < 1e-9), "{reach:?}");
        // A description whose profiles are harmonic (or absent) needs none.
        let harmonic: String = QUARTER_CAR
            .lines()
            .filter(|l| !l.starts_with("    psd:") && !l.starts_with("    wavelengths:"))
            .map(|l| {
                let l = l.replace(
                    "kind: generated",
                    "kind: harmonic\n    amplitude: 0.01\n    wavelength: 10.0",
                );
                l + "\n"
            })
            .collect();
        let none = generated_profile_reach(&compile(&harmonic), &run(5.0, 0.0));
        assert_eq!(none.unwrap(), None);
    }

    /// With the profiles switched on late, the point has travelled `v t_on` by then, least at
    /// the lowest sampled speed (36 km/h = 10 m/s over 0.2 s: 2 m); the corner is named.
    #[test]
    fn the_least_position_over_the_sampling_box_is_checked() {
        let system = compile(QUARTER_CAR);
        let e = check_profile_starts(&system, &run(-20.0, 0.1)).unwrap_err();
        let text = e.to_string();
        assert!(text.contains("reads it from x = -18 m"), "{text}");
        assert!(
            text.contains("at x0 +2 m when the profiles come on, t = 0.2 s"),
            "{text}"
        );
        assert!(text.contains("least at v_kmh = 36"), "{text}");
        assert!(text.contains("set x0 >= -2 m"), "{text}");
        check_profile_starts(&system, &run(-2.0, 0.1)).unwrap();
        assert!(check_profile_starts(&system, &run(-2.01, 0.1)).is_err());
        // An overridden range moves the extreme.
        let mut values = BTreeMap::new();
        values.insert("v_kmh".to_owned(), Override::Range([72.0, 108.0]));
        let faster = mbd_system::load_str(QUARTER_CAR, "car.yaml", &values).unwrap();
        check_profile_starts(&faster, &run(-4.0, 0.1)).unwrap();
        assert!(check_profile_starts(&faster, &run(-4.01, 0.1)).is_err());
    }

    /// An offset that is an expression of a sampled parameter is taken at its least.
    #[test]
    fn a_sampled_offset_is_taken_at_its_least() {
        let text = QUARTER_CAR
            .replacen(
                "  g: {unit: m/s^2",
                "  o: {unit: m, nominal: 1, range: [-3, 2]}\n  g: {unit: m/s^2",
                1,
            )
            .replacen(
                "road: {on: ground, offset: 0}",
                "road: {on: ground, offset: 2 * o}",
                1,
            );
        let system = compile(&text);
        let e = check_profile_starts(&system, &run(5.0, 0.0)).unwrap_err();
        let text = e.to_string();
        assert!(text.contains("reads it from x = -1 m"), "{text}");
        assert!(text.contains("least at o = -3"), "{text}");
        assert!(text.contains("set x0 >= 6 m"), "{text}");
        check_profile_starts(&system, &run(6.0, 0.0)).unwrap();
    }

    /// A harmonic profile covers every `x`: nothing to refuse.
    #[test]
    fn a_harmonic_profile_covers_every_start() {
        let text = QUARTER_CAR.replacen(
            "    kind: generated\n    psd: {iso8608: C}",
            "    kind: harmonic\n    amplitude: 1.0e-3\n    wavelength: 5",
            1,
        );
        let text = text
            .lines()
            .filter(|l| !l.trim_start().starts_with("wavelengths:"))
            .collect::<Vec<_>>()
            .join("\n");
        check_profile_starts(&compile(&text), &run(-20.0, 0.0)).unwrap();
    }

    /// The check mode's report: `file:line:col` of the profile in the description, its name,
    /// what was found and the fix.
    #[test]
    fn the_refusal_is_placed_at_the_profiles_line() {
        let source = SystemSource {
            file: "systems/car.yaml".into(),
            text: QUARTER_CAR.into(),
            values: BTreeMap::new(),
        };
        let system = source.compile().unwrap();
        let line = 1 + QUARTER_CAR
            .lines()
            .position(|l| l == "  road:")
            .expect("the profile's entry");
        let e = check_profile_starts_described(&source, &system, &run(-20.0, 0.0)).unwrap_err();
        assert!(matches!(e, Error::Described(_)), "{e}");
        let text = e.to_string();
        // The example of docs/systems.md, "What is refused".
        assert_eq!(line, 30);
        assert_eq!(
            text,
            "systems/car.yaml:30:3: profiles.road: x0 = -20 m: the generated profile `road` covers [0, length) but element `tyre` reads it from x = -20 m (its point `road` at x0 +0 m); set x0 >= 0 m, or make `road` a harmonic profile (it covers every x)"
        );
        check_profile_starts_described(&source, &system, &run(5.0, 0.0)).unwrap();
    }

    /// The shipped descriptions pass with the start positions of their shipped pipelines
    /// (`pipeline.yaml` and `configs/`: vtcd 20 m, quarter car 5 m, bridge 0 m, vtcd-3d 20 m).
    #[test]
    fn the_shipped_systems_pass_from_their_shipped_starts() {
        for (text, x0) in [
            (include_str!("../../../systems/vtcd.yaml"), 20.0),
            (QUARTER_CAR, 5.0),
            (include_str!("../../../systems/bridge.yaml"), 0.0),
            (include_str!("../../../systems/vtcd-3d.yaml"), 20.0),
        ] {
            let system = compile(text);
            check_profile_starts(&system, &run(x0, 0.0)).unwrap_or_else(|e| panic!("{e}"));
            assert!(check_profile_starts(&system, &run(-1.0, 0.0)).is_err());
        }
    }
}
