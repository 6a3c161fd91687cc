// Mitsuba 3 integrator plugin `lacquer_path`: a unidirectional path tracer (next-event
// estimation and BSDF sampling combined with the power heuristic, Russian roulette) that keeps
// the camera ray's differentials, so BSDFs that ask for them (`NeedsDifferentials`, e.g. the
// `lacquer` BSDF with a sparkle paint) get uv partials at the first hit. Mitsuba's own `path`
// integrator converts the camera ray to a plain Ray3f, so sparkle never sees a footprint
// there (deeper vertices use the mean lobe in both).
//
// Parameters: max_depth (int, default -1 = unlimited; Mitsuba's meaning: 1 = only directly
// visible emitters), rr_depth (int, default 5), hide_emitters (bool, default false).
// Variants: scalar_rgb, scalar_spectral, llvm_ad_rgb (wavefront mode: the bounce loop is an
// ordinary C++ loop that evaluates its state each iteration, so BSDF and emitter calls are
// evaluated calls; it does not use Dr.Jit's symbolic loops).

#include <mitsuba/core/properties.h>
#include <mitsuba/render/bsdf.h>
#include <mitsuba/render/emitter.h>
#include <mitsuba/render/integrator.h>
#include <mitsuba/render/records.h>

NAMESPACE_BEGIN(mitsuba)

template <typename Float, typename Spectrum>
class LacquerPathIntegrator final : public MonteCarloIntegrator<Float, Spectrum> {
public:
    MI_IMPORT_BASE(MonteCarloIntegrator, m_max_depth, m_rr_depth, m_hide_emitters)
    MI_IMPORT_TYPES(Scene, Sampler, Medium, Emitter, EmitterPtr, BSDF, BSDFPtr)

    LacquerPathIntegrator(const Properties &props) : Base(props) {}

    std::pair<Spectrum, Mask> sample(const Scene *scene, Sampler *sampler,
                                     const RayDifferential3f &camera_ray,
                                     const Medium * /* medium */, Float * /* aovs */,
                                     Mask active) const override {
        MI_MASKED_FUNCTION(ProfilerPhase::SamplingIntegratorSample, active);
        if (unlikely(m_max_depth == 0))
            return { 0.f, false };

        Ray3f ray(camera_ray);
        Spectrum throughput(1.f), result(0.f);
        Float eta(1.f);
        Interaction3f prev_it = dr::zeros<Interaction3f>();
        Float prev_bsdf_pdf(1.f);
        Mask prev_bsdf_delta(true);
        Mask valid_ray = false;
        BSDFContext ctx;

        for (uint32_t depth = 0;; ++depth) {
            SurfaceInteraction3f si = scene->ray_intersect(ray, +RayFlags::All, depth == 0, active);
            if (depth == 0)
                valid_ray = si.is_valid();

            // ---- emitter hit by the previous BSDF sample (or seen directly) ----
            EmitterPtr emitter = si.emitter(scene, active);
            Mask hit_emitter = active && (emitter != nullptr);
            if (depth == 0 && m_hide_emitters)
                hit_emitter = false;
            if (dr::any_or<true>(hit_emitter)) {
                DirectionSample3f ds(scene, si, prev_it);
                Float em_pdf = 0.f;
                if (depth > 0)
                    em_pdf = scene->pdf_emitter_direction(prev_it, ds, hit_emitter && !prev_bsdf_delta);
                Float mis = power_heuristic(prev_bsdf_pdf, em_pdf);
                Spectrum le = emitter->eval(si, hit_emitter);
                result = dr::select(hit_emitter, dr::fmadd(throughput, le * mis, result), result);
            }

            Mask active_next = active && si.is_valid() && (depth + 1 < m_max_depth);
            if (none_left(active_next))
                break;

            // The camera hit keeps the ray differentials: uv partials for BSDFs that want them.
            // (Computed here rather than by si.bsdf(ray), which in JIT variants takes the
            // zero-initialised partials of a fresh interaction for computed ones.)
            BSDFPtr bsdf = si.bsdf();
            if (depth == 0 && camera_ray.has_differentials &&
                dr::any_or<true>(active_next && bsdf->needs_differentials()))
                si.compute_uv_partials(camera_ray);

            // ---- next-event estimation ----
            Mask active_em = active_next && has_flag(bsdf->flags(), BSDFFlags::Smooth);
            if (dr::any_or<true>(active_em)) {
                auto [ds, em_weight] = scene->sample_emitter_direction(si, sampler->next_2d(active_em), true, active_em);
                active_em &= ds.pdf != 0.f;
                Vector3f wo = si.to_local(ds.d);
                auto [bsdf_val, bsdf_pdf] = bsdf->eval_pdf(ctx, si, wo, active_em);
                Float mis = dr::select(ds.delta, 1.f, power_heuristic(ds.pdf, bsdf_pdf));
                result = dr::select(active_em, dr::fmadd(throughput, bsdf_val * em_weight * mis, result), result);
            }

            // ---- BSDF sampling ----
            Float s1 = sampler->next_1d(active_next);
            Point2f s2 = sampler->next_2d(active_next);
            auto [bs, bsdf_weight] = bsdf->sample(ctx, si, s1, s2, active_next);
            Mask sampled = active_next && bs.pdf > 0.f;
            ray = dr::select(sampled, si.spawn_ray(si.to_world(bs.wo)), ray);
            throughput = dr::select(sampled, throughput * bsdf_weight, 0.f);
            eta = dr::select(sampled, eta * bs.eta, eta);
            prev_it = dr::select(sampled, Interaction3f(si), prev_it);
            prev_bsdf_pdf = dr::select(sampled, bs.pdf, prev_bsdf_pdf);
            prev_bsdf_delta = dr::select(sampled, has_flag(bs.sampled_type, BSDFFlags::Delta), prev_bsdf_delta);

            // ---- Russian roulette ----
            Float tp_max = dr::max(unpolarized_spectrum(throughput)) * dr::square(eta);
            active = sampled && tp_max > 0.f;
            if (depth + 1 >= m_rr_depth) {
                Float q = dr::minimum(tp_max, .95f);
                Mask survive = sampler->next_1d(active) < q;
                throughput = dr::select(active && survive, throughput / q, throughput);
                active &= survive;
            }

            if constexpr (dr::is_jit_v<Float>) {
                sampler->schedule_state();  // the random number generator's state
                dr::eval(ray, throughput, result, eta, prev_it, prev_bsdf_pdf, prev_bsdf_delta, active);
            }
        }
        return { result, valid_ray };
    }

    std::string to_string() const override {
        return tfm::format("LacquerPathIntegrator[max_depth = %u, rr_depth = %u]", m_max_depth, m_rr_depth);
    }

    MI_DECLARE_CLASS(LacquerPathIntegrator)

private:
    static Float power_heuristic(Float a, Float b) {
        Float a2 = dr::square(a), b2 = dr::square(b);
        return dr::select(a2 + b2 > 0.f, a2 / (a2 + b2), 0.f);
    }

    static bool none_left(const Mask &m) {
        if constexpr (dr::is_jit_v<Float>)
            return !dr::any(m);
        else
            return !m;
    }
};

NAMESPACE_END(mitsuba)

extern "C" MI_EXPORT void init_plugin(std::string_view name, mitsuba::PluginRegisterFn fn) {
    using namespace mitsuba;
    fn(name, "scalar_rgb", ObjectType::Integrator, [](void *, const Properties &p) -> ref<Object> {
        return new LacquerPathIntegrator<float, Color<float, 3>>(p);
    });
    fn(name, "scalar_spectral", ObjectType::Integrator, [](void *, const Properties &p) -> ref<Object> {
        return new LacquerPathIntegrator<float, Spectrum<float, 4>>(p);
    });
#if defined(LACQUER_WITH_LLVM)
    using FloatL = dr::DiffArray<JitBackend::LLVM, float>;
    fn(name, "llvm_ad_rgb", ObjectType::Integrator, [](void *, const Properties &p) -> ref<Object> {
        return new LacquerPathIntegrator<FloatL, Color<FloatL, 3>>(p);
    });
    fn(name, "llvm_ad_spectral", ObjectType::Integrator, [](void *, const Properties &p) -> ref<Object> {
        return new LacquerPathIntegrator<FloatL, Spectrum<FloatL, 4>>(p);
    });
#endif
}
