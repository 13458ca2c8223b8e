//! The fast one-contact-phase admissibility used by the scans ([`examine_one_contact`]: y-signal
//! formulation, class-0 prefilter, reused buffers) against the straightforward path
//! ([`examine`]: signed permutation, kernel basis, one trajectory per basis vector).

use signorini_core::modal::fast::{Scratch, class_zero_can_be_admissible, examine_one_contact};
use signorini_core::modal::{BACKBONE_COLUMNS, BackbonePoint, backbone_row, examine, scan};
use signorini_core::wfem::WaveBar;
use std::ops::ControlFlow;

fn rows_equal(a: &BackbonePoint, b: &BackbonePoint) -> Result<(), String> {
    let (ra, rb) = (backbone_row(a), backbone_row(b));
    for ((name, x), y) in BACKBONE_COLUMNS.iter().zip(&ra).zip(&rb) {
        let same = if x.is_nan() {
            y.is_nan()
        } else {
            (x - y).abs() <= 1e-12 * x.abs()
        };
        if !same {
            return Err(format!("{name}: {x} vs {y} (m = {}, p = {})", a.m, a.p));
        }
    }
    match (&a.orbit, &b.orbit) {
        (Some(o), Some(q)) => {
            let ring_scale = o.ring.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let u_scale = o.u.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let ring_ok = o.ring.len() == q.ring.len()
                && o.ring
                    .iter()
                    .zip(&q.ring)
                    .all(|(x, y)| (x - y).abs() <= 1e-12 * ring_scale);
            let u_ok = o.u.len() == q.u.len()
                && o.u
                    .iter()
                    .zip(&q.u)
                    .all(|(x, y)| (x - y).abs() <= 1e-12 * u_scale);
            if ring_ok && u_ok && o.phases == q.phases && o.kernel_dim == q.kernel_dim {
                Ok(())
            } else {
                Err(format!("orbit differs (m = {}, p = {})", a.m, a.p))
            }
        }
        (None, None) => Ok(()),
        _ => Err(format!("admissibility differs (m = {}, p = {})", a.m, a.p)),
    }
}

#[test]
fn fast_path_gives_the_straightforward_backbone_rows_for_every_candidate() {
    let mut scratch = Scratch::default();
    for n in [17usize, 20] {
        for gap in [1e-3, 0.0, -1e-3] {
            let bar = WaveBar::unit(n, gap);
            let (mut candidates, mut admissible, mut high_h) = (0, 0, 0);
            for t in 2..=4 * n {
                for p in 1..t {
                    let m = t - p;
                    let slow = examine(&bar, m, p, 0);
                    let fast = examine_one_contact(&bar, m, p, &mut scratch);
                    match (&slow, &fast) {
                        (None, None) => {}
                        (Some(a), Some(b)) => {
                            rows_equal(a, b).unwrap_or_else(|e| panic!("N = {n}, g0 = {gap}: {e}"));
                            candidates += 1;
                            if a.orbit.is_some() {
                                admissible += 1;
                                high_h += usize::from(a.kernel_dim >= 2);
                                // The prefilter is a necessary condition.
                                assert!(class_zero_can_be_admissible(n, m, p));
                            }
                        }
                        _ => panic!("N = {n}, g0 = {gap}, (m, p) = ({m}, {p}): kernel differs"),
                    }
                }
            }
            // The comparison covers many admissible orbits, with multi-dimensional kernels too.
            assert!(candidates > 1000, "N = {n}, g0 = {gap}: {candidates}");
            assert!(admissible >= 19, "N = {n}, g0 = {gap}: {admissible}");
            assert!(high_h >= 10, "N = {n}, g0 = {gap}: {high_h}");
        }
    }
}

#[test]
fn scan_rows_equal_the_straightforward_scan() {
    let n = 24;
    for gap in [1e-3, 0.0, -1e-3] {
        let bar = WaveBar::unit(n, gap);
        for all_candidates in [false, true] {
            let fast = scan(&bar, (2, 4 * n), 1, all_candidates, 2, &|| {
                ControlFlow::Continue(())
            })
            .expect("scan");
            let mut slow: Vec<BackbonePoint> = (2..=4 * n)
                .flat_map(|t| (1..t).map(move |p| (t - p, p)))
                .filter_map(|(m, p)| examine(&bar, m, p, 0))
                .filter(|pt| all_candidates || pt.orbit.is_some())
                .collect();
            slow.sort_by_key(|pt| (pt.m + pt.p, pt.m, pt.p));
            assert_eq!(fast.len(), slow.len(), "g0 = {gap}");
            assert!(fast.len() > 30);
            for (a, b) in slow.iter().zip(&fast) {
                rows_equal(a, b).unwrap_or_else(|e| panic!("g0 = {gap}: {e}"));
            }
        }
    }
}
