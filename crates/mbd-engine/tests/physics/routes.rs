//! The fast path (sine transforms of the uniform supports; the closed-form static equilibrium
//! of a statically determinate vehicle) against the general route (dense mode shapes at the
//! supports; Newton's method on the whole state), on the vehicle-track model on a short track.
//! Tolerance 1e-10 per column, `max |a - b| / max |b|` (`systems-interfaces.md`): the two
//! routes sum the same terms in a different order, so they differ by round-off amplified by
//! the run (measured below 1e-12 for the dynamics), and the general statics stop at a force
//! residual of 1e-12 of the load.

use crate::common::*;
use mbd_engine::{Route, StartMode};

#[test]
fn fast_path_equals_the_general_route_for_dynamics_and_equilibrium() {
    let system = short_track(&system_text("vtcd.yaml"), &[]);
    let sampled = system.nominal();
    for start in [StartMode::Equilibrium, StartMode::Rest] {
        let cfg = config(0.1, 1e-4, 10, start, SHORT_X0);
        let profiles = || vec![Some(track_profile(3))];
        let fast = engine(&system, &sampled, &cfg, profiles(), Route::Fast);
        let general = engine(&system, &sampled, &cfg, profiles(), Route::General);
        assert!(fast.uses_fast_path(0) && !general.uses_fast_path(0));
        // The equilibrium state, part by part (rigid DOFs, modes, support levels).
        let (xf, xg) = (
            fast.initial_state().unwrap(),
            general.initial_state().unwrap(),
        );
        let layout = fast.layout();
        let parts = [
            ("rigid", 0..layout.rigid),
            ("modes", layout.beams[0].modes.clone()),
            ("supports", layout.beams[0].supports.clone()),
        ];
        for (name, range) in parts {
            if start == StartMode::Rest {
                assert!(xf[range.clone()]
                    .iter()
                    .chain(&xg[range])
                    .all(|x| *x == 0.0));
                continue;
            }
            let e = relative_error(&xf[range.clone()], &xg[range.clone()]);
            println!("equilibrium {name}: {e:.2e} (max {:.3e})", peak(&xg[range]));
            assert!(e < 1e-10, "equilibrium {name}: {e:e}");
        }
        let (a, b) = (fast.run().unwrap(), general.run().unwrap());
        assert_eq!(a.t, b.t);
        let mut worst = (0.0, "");
        for (i, ch) in system.channels.iter().enumerate() {
            let e = relative_error(&a.columns[i], &b.columns[i]);
            assert!(
                peak(&b.columns[i]) > 0.0 || ch.name.starts_with("eta"),
                "{} is zero",
                ch.name
            );
            if e > worst.0 {
                worst = (e, ch.name.as_str());
            }
            assert!(e < 1e-10, "{start:?} {}: {e:e}", ch.name);
        }
        println!(
            "{start:?}: largest column difference {:.2e} ({})",
            worst.0, worst.1
        );
    }
}
