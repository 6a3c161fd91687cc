//! Pixel statistics of rendered sparkle against an explicit flake simulation (issue 17,
//! item 1): a painted plane under a point light at the camera's mirror direction, rendered
//! by `lacquer render`'s job path (`render_job`, jittered camera rays, 8 spp, direct
//! lighting) and simulated flake by flake (`flake_sim`), at 2 % and 8 % flakes and at two
//! camera distances (pixel footprints of 25 and 100 flat-lying flakes at 8 %).
//!
//! Compared per configuration, on the flake multiplier `r = (L − L_rest)/L_flakes` of
//! 128 × 128 pixels: mean, variance, fraction of glinting pixels and the histogram of
//! glinting flakes per pixel (0, 1, 2, ≥ 3).
//!
//! Before issue 17 every jittered sample got a footprint centred on itself, so a pixel
//! averaged the counts of the 1–4 grid cells its shifted footprints overlapped: the render's
//! variance was 0.51–0.56 of the simulation's (z −7 to −27), 17–25 % fewer pixels showed half a
//! flake's glint or more and two-flake pixels were 2–5× too rare (numbers in
//! docs/paint-validation.md §4); this test failed on every configuration.
//!
//! `cargo test -p lacquer-render --test sparkle_pixels -- --nocapture` prints the table.

mod flake_sim;

use flake_sim::{pixels, render_multipliers, simulate, stats, PixelStats, PlaneSetup};

fn setups() -> Vec<PlaneSetup> {
    let mut v = Vec::new();
    for density_pct in [2.0, 8.0] {
        // 128 px over 5°: 6.8e-4 rad per pixel; at 30° from the normal the footprint holds
        // 25 (427 mm) or 100 (854 mm) flat-lying 20 µm flakes at 8 %.
        for distance_mm in [427.0, 854.0] {
            v.push(PlaneSetup {
                density_pct,
                distance_mm,
                pixels: 128,
                fov_deg: 5.0,
                theta_deg: 30.0,
                light_distance_mm: 500.0,
                intensity: 1000.0,
            });
        }
    }
    v
}

fn line(name: &str, s: &PixelStats) -> String {
    format!(
        "{name:>6}: mean {:.4} var {:.3} glint {:.4} hist {:?} neighbour corr {:.3}",
        s.mean, s.var, s.glint, s.hist, s.neighbour_corr
    )
}

/// χ² of a 2 × 4 contingency table (bins with fewer than 10 counts in both merged into the
/// previous one) and its degrees of freedom.
fn chi2_two_samples(a: &[usize; 4], b: &[usize; 4]) -> (f64, usize) {
    let (mut ma, mut mb) = (vec![a[0]], vec![b[0]]);
    for i in 1..4 {
        if a[i] + b[i] < 20 {
            *ma.last_mut().unwrap() += a[i];
            *mb.last_mut().unwrap() += b[i];
        } else {
            ma.push(a[i]);
            mb.push(b[i]);
        }
    }
    let (na, nb) = (ma.iter().sum::<usize>() as f64, mb.iter().sum::<usize>() as f64);
    let mut chi2 = 0.0;
    for (x, y) in ma.iter().zip(&mb) {
        let tot = (*x + *y) as f64;
        let (ea, eb) = (tot * na / (na + nb), tot * nb / (na + nb));
        chi2 += (*x as f64 - ea).powi(2) / ea + (*y as f64 - eb).powi(2) / eb;
    }
    (chi2, ma.len() - 1)
}

#[test]
fn rendered_sparkle_has_the_pixel_statistics_of_explicit_flakes() {
    let mut failures = Vec::new();
    for (k, setup) in setups().iter().enumerate() {
        let px = pixels(setup);
        let sim = simulate(setup, &px, 1000 + k as u64);
        let fb = lacquer_render::render_job(&setup.job_json(8), &mut |_| true).unwrap();
        let ren = render_multipliers(&px, &fb.color);
        let n = setup.pixels as usize;
        let (s, r) = (stats(&sim, &px, n), stats(&ren, &px, n));
        let lambda = px.lambda.iter().sum::<f64>() / px.lambda.len() as f64;
        eprintln!(
            "density {} %, distance {} mm: N p = {lambda:.4} (1/(N p) = {:.2})\n{}\n{}",
            setup.density_pct,
            setup.distance_mm,
            1.0 / lambda,
            line("sim", &s),
            line("render", &r)
        );
        // Mean: both estimate 1; standard error from the simulation's variance (the render's
        // is the same law); 4.5 combined standard errors.
        let se_mean = ((s.var + r.var) / s.n as f64).sqrt();
        // Variance: the log ratio's standard error from each sample's fourth moment,
        // Var(s²) ≈ (m4 − σ⁴)/n; 4.5 standard errors (measured |z| ≤ 1.7 after the fix).
        let se_log_var =
            ((s.m4 / (s.var * s.var) - 1.0) / s.n as f64 + (r.m4 / (r.var * r.var) - 1.0) / r.n as f64).sqrt();
        let z_var = (r.var / s.var).ln() / se_log_var;
        // Glinting fraction: two-proportion z, 4.5 standard errors.
        let pg = 0.5 * (s.glint + r.glint);
        let z_glint = (r.glint - s.glint) / (2.0 * pg * (1.0 - pg) / s.n as f64).sqrt();
        // Histogram: χ² of the 2 × 4 table; 1e-4 critical values (15.1, 18.4, 21.1 for 1–3 dof).
        let (chi2, dof) = chi2_two_samples(&s.hist, &r.hist);
        let crit = [0.0, 15.1, 18.4, 21.1][dof];
        let z_mean = (r.mean - s.mean) / se_mean;
        eprintln!(
            "        z(mean) {z_mean:.2}, var ratio {:.3} (z {z_var:.2}), z(glint) {z_glint:.2}, χ² {chi2:.1} / {dof} dof",
            r.var / s.var
        );
        if z_mean.abs() > 4.5 {
            failures.push(format!("{k}: mean {} vs {}", r.mean, s.mean));
        }
        if z_var.abs() > 4.5 {
            failures.push(format!("{k}: variance {} vs {} (ratio {:.3})", r.var, s.var, r.var / s.var));
        }
        if z_glint.abs() > 4.5 {
            failures.push(format!("{k}: glinting pixels {} vs {}", r.glint, s.glint));
        }
        if chi2 > crit {
            failures.push(format!("{k}: histogram {:?} vs {:?} (χ² {chi2:.1})", r.hist, s.hist));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
