//! The work queue behind [`super::check_everything`], [`super::check_all`],
//! [`super::check_model`] and [`super::check_presets`].
//!
//! The unit of work is one part of one material's check — the checks other than χ² (one
//! item), one χ² direction (one item each), one χ² retest direction (queued when the first
//! stage of that material asks for it) — or one parameter-extremes set of a model, or the
//! planning of a model (building its defaults, check sets and random parameter sets, which
//! queues the rest). Threads take the most expensive queued item first (estimated from a
//! timing of the material's sample/eval/pdf), so the slow models start early and both
//! cores stay busy to the end.
//!
//! Every item uses its own random stream, chosen exactly as the single-threaded code chose
//! it (`chi2_direction` starts the stream where the serial loop would be), and the results
//! are assembled in the serial order: the reports do not depend on the number of threads or
//! on the order items ran in (`tests::reports_do_not_depend_on_threads`).

use super::{
    base_parts, chi2_direction, chi2_needs_retest, extreme_parameter_sets, extreme_set_hard_cases, finish_model, judge,
    plan_model, retest_config, BaseParts, CheckConfig, Chi2Case, HardCaseReport, ModelReport, PresetReport, Profile,
};
use crate::bxdf::ModelInfo;
use crate::material::Material;
use crate::presets::Preset;
use serde_json::{Map, Value};
use std::sync::{Arc, Condvar, Mutex};

/// One item of work.
#[derive(Clone, Copy, Debug)]
enum Job {
    /// Build the materials of model `m` and queue their items.
    Plan(usize),
    /// Hard cases of extreme parameter set `set` of model `m`.
    Extreme { model: usize, set: usize },
    /// The checks of material `unit` other than χ².
    Base(usize),
    /// χ² direction `k` of material `unit` (`retest`: the second stage's configuration).
    Chi2 { unit: usize, k: usize, retest: bool },
}

/// What a job produced.
// One value per finished work item, moved once into its slot: the variants' sizes do not
// matter, and boxing the largest would only add an allocation per item.
#[allow(clippy::large_enum_variant)]
enum Output {
    Plan(super::ModelPlan),
    Extreme(Result<HardCaseReport, String>),
    Base(BaseParts),
    Chi2(Chi2Case),
}

/// One material being checked.
struct Unit {
    material: Arc<Material>,
    cfg: CheckConfig,
    origin: &'static str,
    /// Estimated seconds per sample + eval + pdf (scheduling only).
    cost: f64,
    base: Option<BaseParts>,
    chi2: Vec<Option<Chi2Case>>,
    retest: Vec<Option<Chi2Case>>,
}

struct ModelState {
    info: &'static ModelInfo,
    units: Vec<usize>,
    build_errors: Vec<String>,
    sets: Vec<Map<String, Value>>,
    extremes: Vec<Option<Result<HardCaseReport, String>>>,
    cost: f64,
}

#[derive(Default)]
struct State {
    queue: Vec<(f64, Job)>,
    in_flight: usize,
    units: Vec<Unit>,
    models: Vec<ModelState>,
    panicked: Option<Box<dyn std::any::Any + Send>>,
}

/// Seconds per sample + eval + pdf of `m`, timed on a few calls (only orders the queue).
fn time_per_call(m: &Material) -> f64 {
    let wo = super::direction(0.6, 0.4);
    let start = std::time::Instant::now();
    let mut sink = 0.0;
    for i in 0..16 {
        let u = [(i as f64 + 0.5) / 16.0, 0.37, 0.71];
        if let Some(s) = m.sample(wo, u) {
            sink += m.eval(s.wi, wo)[0] + m.pdf(s.wi, wo);
        }
    }
    std::hint::black_box(sink);
    start.elapsed().as_secs_f64() / 16.0 + 1e-8
}

/// Rough work (sample/eval/pdf calls) of a material's non-χ² checks and of one χ² direction.
fn base_calls(cfg: &CheckConfig) -> f64 {
    let furnace = (cfg.furnace_cos.len() * cfg.furnace_phi.len() * cfg.furnace_samples) as f64 * 2.0;
    furnace + cfg.reciprocity_pairs as f64 + 60_000.0
}

fn chi2_calls(cfg: &CheckConfig) -> f64 {
    cfg.chi2_samples as f64 + 20.0 * (cfg.chi2_theta_bins * cfg.chi2_phi_bins) as f64
}

impl State {
    fn push_unit(&mut self, material: Material, cfg: &CheckConfig, origin: &'static str, run_chi2: bool) -> usize {
        let cost = time_per_call(&material);
        let directions = if run_chi2 && material.info().claims.sampled { cfg.chi2_directions.len() } else { 0 };
        let i = self.units.len();
        self.queue.push((cost * base_calls(cfg), Job::Base(i)));
        for k in 0..directions {
            self.queue.push((cost * chi2_calls(cfg), Job::Chi2 { unit: i, k, retest: false }));
        }
        self.units.push(Unit {
            material: Arc::new(material),
            cfg: cfg.clone(),
            origin,
            cost,
            base: None,
            chi2: vec![None; directions],
            retest: Vec::new(),
        });
        i
    }

    /// The queued job with the largest estimated cost.
    fn pop(&mut self) -> Option<Job> {
        let best = (0..self.queue.len()).max_by(|&a, &b| self.queue[a].0.total_cmp(&self.queue[b].0))?;
        Some(self.queue.swap_remove(best).1)
    }

    fn apply(&mut self, job: Job, out: Output, profile: &Profile) {
        match (job, out) {
            (Job::Plan(mi), Output::Plan(plan)) => {
                let info = self.models[mi].info;
                let cfg = profile.config_for(info.name);
                let mut cost = 0.0f64;
                for (m, origin, run_chi2) in plan.materials {
                    let u = self.push_unit(m, cfg, origin, run_chi2);
                    cost = cost.max(self.units[u].cost);
                    self.models[mi].units.push(u);
                }
                let model = &mut self.models[mi];
                model.build_errors = plan.build_errors;
                model.cost = cost;
                for set in 0..model.sets.len() {
                    self.queue.push((cost * 40_000.0, Job::Extreme { model: mi, set }));
                }
            }
            (Job::Extreme { model, set }, Output::Extreme(r)) => self.models[model].extremes[set] = Some(r),
            (Job::Base(u), Output::Base(b)) => self.units[u].base = Some(b),
            (Job::Chi2 { unit, k, retest: false }, Output::Chi2(c)) => {
                let u = &mut self.units[unit];
                u.chi2[k] = Some(c);
                if u.chi2.iter().all(Option::is_some) {
                    let first: Vec<Chi2Case> = u.chi2.iter().flatten().cloned().collect();
                    if chi2_needs_retest(&first, &u.cfg) {
                        let rcfg = retest_config(&u.cfg);
                        u.retest = vec![None; first.len()];
                        let cost = u.cost * chi2_calls(&rcfg);
                        for k in 0..first.len() {
                            self.queue.push((cost, Job::Chi2 { unit, k, retest: true }));
                        }
                    }
                }
            }
            (Job::Chi2 { unit, k, retest: true }, Output::Chi2(c)) => self.units[unit].retest[k] = Some(c),
            _ => unreachable!("every job produces its own kind of output"),
        }
    }
}

/// Runs one job (no lock held).
fn execute(job: Job, st: &Mutex<State>, profile: &Profile) -> Output {
    match job {
        Job::Plan(mi) => {
            let info = st.lock().expect("queue lock").models[mi].info;
            Output::Plan(plan_model(info, profile.config_for(info.name)))
        }
        Job::Extreme { model, set } => {
            let (info, obj) = {
                let g = st.lock().expect("queue lock");
                (g.models[model].info, g.models[model].sets[set].clone())
            };
            Output::Extreme(extreme_set_hard_cases(info, &obj))
        }
        Job::Base(u) => {
            let (m, cfg) = {
                let g = st.lock().expect("queue lock");
                (Arc::clone(&g.units[u].material), g.units[u].cfg.clone())
            };
            Output::Base(base_parts(&m, &cfg))
        }
        Job::Chi2 { unit, k, retest } => {
            let (m, cfg) = {
                let g = st.lock().expect("queue lock");
                (Arc::clone(&g.units[unit].material), g.units[unit].cfg.clone())
            };
            let cfg = if retest { retest_config(&cfg) } else { cfg };
            Output::Chi2(chi2_direction(&m, &cfg, k))
        }
    }
}

fn worker(st: &Mutex<State>, ready: &Condvar, profile: &Profile) {
    loop {
        let job = {
            let mut g = st.lock().expect("queue lock");
            loop {
                if g.panicked.is_some() {
                    return;
                }
                if let Some(j) = g.pop() {
                    g.in_flight += 1;
                    break j;
                }
                if g.in_flight == 0 {
                    return;
                }
                g = ready.wait(g).expect("queue lock");
            }
        };
        let out = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| execute(job, st, profile)));
        let mut g = st.lock().expect("queue lock");
        g.in_flight -= 1;
        match out {
            Ok(out) => g.apply(job, out, profile),
            Err(payload) => g.panicked = Some(payload),
        }
        ready.notify_all();
    }
}

/// The report of a finished material.
fn unit_report(units: &mut [Unit], u: usize) -> super::MaterialReport {
    let unit = &mut units[u];
    let chi2 = unit.chi2.drain(..).map(|c| c.expect("χ² item ran")).collect();
    let retest = unit.retest.drain(..).map(|c| c.expect("χ² retest item ran")).collect();
    let base = unit.base.take().expect("base item ran");
    judge(&unit.material, &unit.cfg, unit.origin, base, chi2, retest)
}

/// Checks `models` and `presets` under `profile` on `threads` threads (1: the calling thread).
pub(super) fn run(
    profile: &Profile,
    models: &[&'static ModelInfo],
    presets: &[&'static Preset],
    threads: usize,
) -> (Vec<ModelReport>, Vec<PresetReport>) {
    let mut state = State::default();
    for (mi, &info) in models.iter().enumerate() {
        let sets = extreme_parameter_sets(info);
        let extremes = vec![None; sets.len()];
        state.models.push(ModelState { info, units: Vec::new(), build_errors: Vec::new(), sets, extremes, cost: 0.0 });
        state.queue.push((f64::INFINITY, Job::Plan(mi)));
    }
    let preset_units: Vec<usize> = presets
        .iter()
        .map(|p| {
            let m = Material::from_json(p.json).expect("presets are valid materials");
            let cfg = profile.config_for(m.info().name);
            state.push_unit(m, cfg, "preset", true)
        })
        .collect();

    let st = Mutex::new(state);
    let ready = Condvar::new();
    if threads <= 1 {
        worker(&st, &ready, profile);
    } else {
        std::thread::scope(|s| {
            for _ in 0..threads {
                s.spawn(|| worker(&st, &ready, profile));
            }
        });
    }
    let mut state = st.into_inner().expect("queue lock");
    if let Some(payload) = state.panicked.take() {
        std::panic::resume_unwind(payload);
    }

    let mut model_reports = Vec::new();
    for mi in 0..models.len() {
        let units = std::mem::take(&mut state.models[mi].units);
        let materials = units.into_iter().map(|u| unit_report(&mut state.units, u)).collect();
        let model = &mut state.models[mi];
        let mut extremes = HardCaseReport::default();
        for r in model.extremes.drain(..) {
            extremes.add_extreme(r.expect("extreme item ran"));
        }
        model_reports.push(finish_model(model.info, materials, extremes, std::mem::take(&mut model.build_errors)));
    }
    let preset_reports = presets
        .iter()
        .zip(preset_units)
        .map(|(p, u)| PresetReport { preset: p.name, report: unit_report(&mut state.units, u) })
        .collect();
    (model_reports, preset_reports)
}

#[cfg(test)]
mod tests {
    use super::super::{check_material, parameter_extremes, CheckConfig, Profile};
    use super::run;
    use crate::models;

    /// A cheap configuration that still runs every part, retests included.
    fn small() -> CheckConfig {
        CheckConfig {
            reciprocity_pairs: 500,
            furnace_cos: vec![1.0, 0.3],
            furnace_phi: vec![0.0],
            furnace_samples: 2_000,
            chi2_samples: 20_000,
            chi2_theta_bins: 8,
            chi2_phi_bins: 16,
            random_param_sets: 2,
            ..CheckConfig::quick()
        }
    }

    /// The reports (every figure, in JSON) are the same with 1 and 2 threads, and the same
    /// as the serial functions `check_material` and `parameter_extremes` produce.
    #[test]
    fn reports_do_not_depend_on_threads() {
        let names = ["lambert", "ward", "oren_nayar"];
        let infos: Vec<_> = names.iter().map(|n| models::find(n).expect("registered")).collect();
        let presets: Vec<_> = crate::presets::PRESETS.iter().take(1).collect();
        // A significance level this high makes first-stage χ² failures (and so retests) likely.
        let cfg = CheckConfig { significance: 0.9, ..small() };
        let profile = Profile::uniform("test", cfg.clone());
        let (reports, preset_reports) = run(&profile, &infos, &presets, 2);
        let two = serde_json::to_string(&(&reports, &preset_reports)).expect("serialisable");
        let one = serde_json::to_string(&run(&profile, &infos, &presets, 1)).expect("serialisable");
        assert_eq!(one, two, "1 vs 2 threads");
        assert!(one.contains("chi2_retest"), "the test should exercise the retest path");

        // The queue's pieces reassemble into what the serial code computes.
        for (r, info) in reports.iter().zip(&infos) {
            let plan = super::plan_model(info, &cfg);
            assert_eq!(r.materials.len(), plan.materials.len());
            for (got, (m, origin, chi2)) in r.materials.iter().zip(&plan.materials) {
                let serial = check_material(m, &cfg, origin, *chi2);
                assert_eq!(serde_json::to_string(got).unwrap(), serde_json::to_string(&serial).unwrap());
            }
            assert_eq!(
                serde_json::to_string(&r.parameter_extremes).unwrap(),
                serde_json::to_string(&parameter_extremes(info)).unwrap()
            );
        }
        for (p, preset) in preset_reports.iter().zip(&presets) {
            let m = crate::Material::from_json(preset.json).unwrap();
            let serial = check_material(&m, &cfg, "preset", true);
            assert_eq!(serde_json::to_string(&p.report).unwrap(), serde_json::to_string(&serial).unwrap());
        }
    }

    /// A profile gives each model its own configuration.
    #[test]
    fn ci_profile_uses_its_configuration_for_the_slow_models() {
        let p = Profile::ci();
        assert!(p.config_for("htsg").chi2_samples < CheckConfig::standard().chi2_samples);
        assert_eq!(p.config_for("ward").chi2_samples, CheckConfig::standard().chi2_samples);
        for name in super::super::CI_REDUCED_MODELS {
            assert!(models::find(name).is_some(), "{name} is registered");
        }
        assert_eq!(Profile::by_name("ci").unwrap().with_seed(7).config_for("stam").seed, 7);
    }

    /// What lets CI skip the quick-configuration checks of rust-core/tests/integration/all_models.rs: for
    /// every model, the `ci` profile checks the same materials (defaults, check sets, and the
    /// quick configuration's random parameter sets, drawn from the same seed) with at least as
    /// many samples, pairs and furnace directions, on the same seed and χ² directions.
    #[test]
    fn ci_profile_covers_the_quick_configuration() {
        let (ci, quick) = (Profile::ci(), CheckConfig::quick());
        for info in models::all() {
            let c = ci.config_for(info.name);
            assert_eq!(c.seed, quick.seed);
            assert_eq!(c.chi2_directions, quick.chi2_directions);
            assert!(c.chi2_samples >= quick.chi2_samples, "{}", info.name);
            assert!(c.chi2_theta_bins >= quick.chi2_theta_bins && c.chi2_phi_bins >= quick.chi2_phi_bins);
            assert!(c.furnace_samples >= quick.furnace_samples, "{}", info.name);
            assert!(c.reciprocity_pairs >= quick.reciprocity_pairs, "{}", info.name);
            assert!(c.random_param_sets >= quick.random_param_sets, "{}", info.name);
            assert!(quick.furnace_cos.iter().all(|x| c.furnace_cos.contains(x)));
            assert!(quick.furnace_phi.iter().all(|x| c.furnace_phi.contains(x)));
            assert!(c.significance >= quick.significance && c.reciprocity_tolerance <= quick.reciprocity_tolerance);
            assert!(c.furnace_tolerance <= quick.furnace_tolerance);
            assert!(c.precision_tolerance <= quick.precision_tolerance);
            let (a, b) = (super::plan_model(info, c), super::plan_model(info, &quick));
            assert_eq!(a.build_errors, b.build_errors);
            for ((ma, oa, ca), (mb, ob, cb)) in a.materials.iter().zip(&b.materials) {
                assert_eq!((ma.to_json(), oa, ca), (mb.to_json(), ob, cb), "{}", info.name);
            }
            assert!(a.materials.len() >= b.materials.len(), "{}", info.name);
        }
    }
}
