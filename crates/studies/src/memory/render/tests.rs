//! Unit tests of the jackknife reduction of grouped renders.

use super::groups::GroupSums;
use speckle_phase::Complex64;
use speckle_stats::jackknife::jackknife;

fn jackknifed(groups: &[GroupSums]) -> (Vec<f64>, Vec<f64>) {
    jackknife(groups.len(), |skip| GroupSums::correlation(groups, skip))
}

#[test]
fn jackknife_of_identical_groups_has_no_error_and_c0_is_one() {
    let g = GroupSums {
        paths: 10.0,
        row0: vec![Complex64::new(2.0, 0.0), Complex64::new(1.0, 1.0)],
        diag: vec![2.0, 3.0],
        single00: 0.0,
    };
    let (c, se) = jackknifed(&[g.clone(), g.clone(), g]);
    assert_eq!(c[0], 1.0);
    assert!((c[1] - 2.0 / 6.0).abs() < 1e-15);
    assert_eq!(se, vec![0.0, 0.0]);
}

#[test]
fn jackknife_of_a_mean_is_the_standard_error_of_the_mean() {
    // With the diagonal fixed at 1 and C_01 = v_g in group g, C(1) is the squared mean of
    // the v_g; its jackknife SE is the delta-method 2 m SE(m) (to 0.02% here).
    let vals = [1.0, 1.2, 0.9, 1.1];
    let groups: Vec<GroupSums> = vals
        .iter()
        .map(|&v| GroupSums {
            paths: 1.0,
            row0: vec![Complex64::ONE, Complex64::new(v, 0.0)],
            diag: vec![1.0, 1.0],
            single00: 0.0,
        })
        .collect();
    let (c, se) = jackknifed(&groups);
    let m = vals.iter().sum::<f64>() / 4.0;
    assert!((c[1] - m * m).abs() < 1e-12);
    let sd = (vals.iter().map(|v| (v - m).powi(2)).sum::<f64>() / 3.0).sqrt();
    let expected = 2.0 * m * sd / 2.0;
    assert!(
        (se[1] / expected - 1.0).abs() < 0.05,
        "{} vs {expected}",
        se[1]
    );
}
