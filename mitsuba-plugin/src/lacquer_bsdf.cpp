// Mitsuba 3 BSDF plugin `lacquer`: any Lacquer material inside a Mitsuba scene.
//
// The plugin is an adapter. It owns no physics: every value comes from the Lacquer core through
// the C ABI (c-api/include/lacquer.h), linked statically from liblacquer.a. What it does:
//
//   Mitsuba                                   Lacquer C ABI
//   si.wi (toward the viewer)                 wo
//   wo argument of eval/pdf (toward light)    wi
//   eval() = f_r * cos(theta_light)           lq_eval = f_r (no cosine)  -> multiplied by cos here
//   sample() value = f_r * cos / pdf          lq_sample weight (identical definition)
//   bs.pdf of a delta sample = probability    lq_sample pdf with LQ_SAMPLE_DELTA (identical)
//   si.uv, si.duv_dx, si.duv_dy               uv, duv (sparkle), only with ray differentials
//   component 0: the smooth lobes             (diffuse for lambert, glossy otherwise)
//   component 1: the clearcoat mirror         LQ_SAMPLE_DELTA samples (smooth-coat paints)
//
// Variants: scalar_rgb, scalar_spectral (the RGB result is upsampled per evaluation with
// Mitsuba's own sRGB model, Jakob & Hanika 2019, scaled for values above 1) and llvm_ad_rgb
// (batched: the arrays are evaluated, one C ABI call per method call; without a sparkle footprint
// the structure-of-arrays calls lq_*_soa read the component arrays and mask bytes in place and
// write into Dr.Jit arrays that become the results; this works only in wavefront mode, i.e.
// with dr.JitFlag.SymbolicLoops and SymbolicCalls off).
//
// Parameters (see docs/mitsuba.md):
//   material   string   Lacquer material JSON, e.g. {"model": "lambert", "albedo": 0.8}
//   preset     string   a Lacquer preset name (exactly one of material / preset)
//   tint       texture  optional reflectance-like multiplier in [0, 1] (e.g. a bitmap): scales
//                       f_r, and so the sample weight; the pdf is unchanged
//   footprint  bool     pass uv and the ray-differential footprint to spatially varying
//                       materials (sparkle); default true

#include <mitsuba/core/properties.h>
#include <mitsuba/core/string.h>
#include <mitsuba/render/bsdf.h>
#include <mitsuba/render/srgb.h>
#include <mitsuba/render/texture.h>

#include <lacquer.h>

#include <algorithm>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

NAMESPACE_BEGIN(mitsuba)

namespace lacquer_detail {

/// Throws a Mitsuba exception for any status except the per-element ones (an invalid
/// direction or u: that element is already 0 / a failed sample, which is what Mitsuba expects).
inline void check(lq_status status, const char *what) {
    if (status == LQ_OK || status == LQ_ERR_INVALID_DIRECTION || status == LQ_ERR_INVALID_ELEMENT)
        return;
    Throw("lacquer: %s failed (%s): %s", what, lq_status_name(status), lq_last_error());
}

struct MaterialDeleter {
    void operator()(lq_material *m) const { lq_material_free(m); }
};
using MaterialPtr = std::shared_ptr<lq_material>;

/// The value of `"key":` in compact canonical JSON (a string or a bare literal), or "".
inline std::string json_field(const std::string &json, const std::string &key) {
    std::string pat = "\"" + key + "\":";
    size_t p = json.find(pat);
    if (p == std::string::npos)
        return "";
    p += pat.size();
    while (p < json.size() && json[p] == ' ')
        ++p;
    if (p < json.size() && json[p] == '"') {
        size_t e = json.find('"', p + 1);
        return e == std::string::npos ? "" : json.substr(p + 1, e - p - 1);
    }
    size_t e = json.find_first_of(",}", p);
    return json.substr(p, e == std::string::npos ? std::string::npos : e - p);
}

} // namespace lacquer_detail

template <typename Float, typename Spectrum>
class LacquerBSDF final : public BSDF<Float, Spectrum> {
public:
    MI_IMPORT_BASE(BSDF, m_flags, m_components)
    MI_IMPORT_TYPES(Texture)

    LacquerBSDF(const Properties &props) : Base(props) {
        using namespace lacquer_detail;
        bool has_material = props.has_property("material"),
             has_preset = props.has_property("preset");
        if (has_material == has_preset)
            Throw("lacquer: give exactly one of \"material\" (material JSON, e.g. "
                  "{\"model\": \"lambert\"}) or \"preset\" (a name from `lacquer presets`)");

        lq_material *raw = nullptr;
        if (has_material) {
            std::string json = props.get<std::string>("material");
            lq_status s = lq_material_from_json(json.c_str(), &raw);
            if (s != LQ_OK)
                Throw("lacquer: invalid \"material\" (%s): %s", lq_status_name(s), lq_last_error());
        } else {
            std::string name = props.get<std::string>("preset");
            lq_status s = lq_material_from_preset(name.c_str(), &raw);
            if (s != LQ_OK)
                Throw("lacquer: invalid \"preset\" (%s): %s", lq_status_name(s), lq_last_error());
        }
        m_material = MaterialPtr(raw, MaterialDeleter());

        char *canonical = nullptr;
        check(lq_material_to_json(raw, &canonical), "lq_material_to_json");
        m_json = canonical;
        lq_string_free(canonical);
        m_model = json_field(m_json, "model");

        if (props.has_property("tint"))
            m_tint = props.get_texture<Texture>("tint", 1.f);

        // Spatially varying (sparkle) materials get uv and the ray-differential footprint.
        m_spatial = props.get<bool>("footprint", true) && json_field(m_json, "sparkle") == "true";

        uint32_t smooth = m_model == "lambert" ? +BSDFFlags::DiffuseReflection
                                               : +BSDFFlags::GlossyReflection;
        m_smooth_type = smooth;
        m_has_delta = probe_delta();

        m_components.clear();
        m_components.push_back(smooth | BSDFFlags::FrontSide);
        if (m_has_delta)
            m_components.push_back(BSDFFlags::DeltaReflection | BSDFFlags::FrontSide);
        m_flags = 0;
        for (uint32_t c : m_components)
            m_flags |= c;
        if (m_spatial)
            m_flags |= +BSDFFlags::NeedsDifferentials;
    }

    void traverse(TraversalCallback *cb) override {
        if (m_tint)
            cb->put("tint", m_tint, ParamFlags::NonDifferentiable);
    }

    // ------------------------------------------------------------------------------------
    // The three verbs (plus the fused eval_pdf)
    // ------------------------------------------------------------------------------------

    std::pair<BSDFSample3f, Spectrum> sample(const BSDFContext &ctx,
                                             const SurfaceInteraction3f &si,
                                             Float sample1, const Point2f &sample2,
                                             Mask active) const override {
        MI_MASKED_FUNCTION(ProfilerPhase::BSDFSample, active);
        BSDFSample3f bs = dr::zeros<BSDFSample3f>();
        bool smooth_on = ctx.is_enabled((BSDFFlags) m_smooth_type, 0),
             delta_on = m_has_delta && ctx.is_enabled(BSDFFlags::DeltaReflection, 1);
        if (!smooth_on && !delta_on)
            return { bs, 0.f };

        if constexpr (!dr::is_jit_v<Float>) {
            if (!active)
                return { bs, 0.f };
            float wo[3] = { si.wi.x(), si.wi.y(), si.wi.z() },
                  u[3] = { sample1, sample2.x(), sample2.y() }, wi[3], weight[3], pdf;
            uint32_t flags = 0;
            if (use_footprint(si)) {
                float uv[2], duv[4];
                spatial_inputs(si, uv, duv);
                lacquer_detail::check(lq_sample_spatial(m_material.get(), 1, wo, u, uv, duv, wi,
                                                        weight, &pdf, &flags),
                                      "lq_sample_spatial");
            } else {
                lacquer_detail::check(
                    lq_sample_one(m_material.get(), wo, u, wi, weight, &pdf, &flags),
                    "lq_sample_one");
            }
            bool delta = (flags & LQ_SAMPLE_DELTA) != 0;
            if ((flags & LQ_SAMPLE_FAILED) || !(pdf > 0.f) || (delta ? !delta_on : !smooth_on))
                return { bs, 0.f };
            bs.wo = Vector3f(wi[0], wi[1], wi[2]);
            bs.pdf = pdf;
            bs.eta = 1.f;
            bs.sampled_type = delta ? +BSDFFlags::DeltaReflection : m_smooth_type;
            bs.sampled_component = delta ? 1u : 0u;
            UnpolarizedSpectrum value = from_rgb(weight, si);
            if (m_tint)
                value *= m_tint->eval(si, active);
            return { bs, depolarizer<Spectrum>(value) };
        } else {
            size_t n = batch_begin("sample", si.wi, sample1, sample2, active);
            Float uv_b, duv_b;
            bool spatial = batch_spatial(si, n, uv_b, duv_b);
            if (!spatial) {
                // Structure of arrays: the library reads the evaluated component arrays and the
                // mask bytes in place and writes into arrays that become the results.
                FloatJ wo_x = lanes(si.wi.x(), n), wo_y = lanes(si.wi.y(), n), wo_z = lanes(si.wi.z(), n),
                       u0 = lanes(sample1, n), u1 = lanes(sample2.x(), n), u2 = lanes(sample2.y(), n);
                MaskJ act = lanes(active, n);
                FloatJ wi_x = outputs<FloatJ>(n), wi_y = outputs<FloatJ>(n), wi_z = outputs<FloatJ>(n),
                       w_r = outputs<FloatJ>(n), w_g = outputs<FloatJ>(n), w_b = outputs<FloatJ>(n),
                       pdf_j = outputs<FloatJ>(n);
                UInt32J fl_j = outputs<UInt32J>(n);
                dr::eval(wo_x, wo_y, wo_z, u0, u1, u2, act);
                const float *px = wo_x.data(), *py = wo_y.data(), *pz = wo_z.data(),
                            *p0 = u0.data(), *p1 = u1.data(), *p2 = u2.data();
                const uint8_t *pa = mask_bytes(act);
                float *o[7] = { wi_x.data(), wi_y.data(), wi_z.data(), w_r.data(), w_g.data(),
                                w_b.data(), pdf_j.data() };
                uint32_t *of = fl_j.data();
                dr::sync_thread();
                lacquer_detail::check(lq_sample_soa(m_material.get(), n, px, py, pz, p0, p1, p2, pa,
                                                    o[0], o[1], o[2], o[3], o[4], o[5], o[6], of),
                                      "lq_sample_soa");
                Float pdf_v(pdf_j);
                UInt32 fl(fl_j);
                Mask delta = (fl & UInt32(LQ_SAMPLE_DELTA)) != 0u;
                Mask ok = active && (fl & UInt32(LQ_SAMPLE_FAILED)) == 0u && pdf_v > 0.f;
                if (!delta_on)
                    ok &= !delta;
                if (!smooth_on)
                    ok &= delta;
                bs.wo = dr::select(ok, Vector3f(Float(wi_x), Float(wi_y), Float(wi_z)), 0.f);
                bs.pdf = dr::select(ok, pdf_v, 0.f);
                bs.eta = 1.f;
                bs.sampled_type = dr::select(delta, UInt32(+BSDFFlags::DeltaReflection), UInt32(m_smooth_type));
                bs.sampled_component = dr::select(delta, UInt32(1u), UInt32(0u));
                UnpolarizedSpectrum value{ Float(w_r), Float(w_g), Float(w_b) };
                if (m_tint)
                    value *= m_tint->eval(si, active);
                return { bs, depolarizer<Spectrum>(value) & ok };
            }
            // Spatial (sparkle): interleaved arrays for lq_sample_spatial.
            Float wo_b = interleave(n, { si.wi.x(), si.wi.y(), si.wi.z() });
            Float u_b = interleave(n, { sample1, sample2.x(), sample2.y() });
            std::vector<float> wi(3 * n), weight(3 * n), pdf(n);
            std::vector<uint32_t> flags(n);
            const float *wo_p = host(wo_b), *u_p = host(u_b);
            lacquer_detail::check(
                lq_sample_spatial(m_material.get(), n, wo_p, u_p,
                                  spatial ? host(uv_b) : nullptr, spatial ? host(duv_b) : nullptr,
                                  wi.data(), weight.data(), pdf.data(), flags.data()),
                "lq_sample_spatial");
            Vector3f wi_v = deinterleave3(wi, n);
            Float pdf_v = dr::load<Float>(pdf.data(), n);
            UInt32 fl = dr::load<UInt32>(flags.data(), n);
            Mask delta = (fl & UInt32(LQ_SAMPLE_DELTA)) != 0u;
            Mask ok = active && (fl & UInt32(LQ_SAMPLE_FAILED)) == 0u && pdf_v > 0.f;
            if (!delta_on)
                ok &= !delta;
            if (!smooth_on)
                ok &= delta;
            bs.wo = dr::select(ok, wi_v, 0.f);
            bs.pdf = dr::select(ok, pdf_v, 0.f);
            bs.eta = 1.f;
            bs.sampled_type = dr::select(delta, UInt32(+BSDFFlags::DeltaReflection), UInt32(m_smooth_type));
            bs.sampled_component = dr::select(delta, UInt32(1u), UInt32(0u));
            Vector3f w = deinterleave3(weight, n);
            UnpolarizedSpectrum value(w.x(), w.y(), w.z());
            if (m_tint)
                value *= m_tint->eval(si, active);
            return { bs, depolarizer<Spectrum>(value) & ok };
        }
    }

    Spectrum eval(const BSDFContext &ctx, const SurfaceInteraction3f &si, const Vector3f &wo,
                  Mask active) const override {
        MI_MASKED_FUNCTION(ProfilerPhase::BSDFEvaluate, active);
        if (!ctx.is_enabled((BSDFFlags) m_smooth_type, 0))
            return 0.f;
        return eval_pdf_impl(si, wo, active, true, false).first;
    }

    Float pdf(const BSDFContext &ctx, const SurfaceInteraction3f &si, const Vector3f &wo,
              Mask active) const override {
        MI_MASKED_FUNCTION(ProfilerPhase::BSDFEvaluate, active);
        if (!ctx.is_enabled((BSDFFlags) m_smooth_type, 0))
            return 0.f;
        return eval_pdf_impl(si, wo, active, false, true).second;
    }

    std::pair<Spectrum, Float> eval_pdf(const BSDFContext &ctx, const SurfaceInteraction3f &si,
                                        const Vector3f &wo, Mask active) const override {
        MI_MASKED_FUNCTION(ProfilerPhase::BSDFEvaluate, active);
        if (!ctx.is_enabled((BSDFFlags) m_smooth_type, 0))
            return { 0.f, 0.f };
        return eval_pdf_impl(si, wo, active, true, true);
    }

    std::string to_string() const override {
        std::ostringstream oss;
        oss << "LacquerBSDF[" << std::endl
            << "  model = \"" << m_model << "\"," << std::endl
            << "  material = " << m_json << "," << std::endl
            << "  delta_lobe = " << (m_has_delta ? "true" : "false") << "," << std::endl
            << "  footprint = " << (m_spatial ? "true" : "false") << "," << std::endl
            << "  tint = " << (m_tint ? string::indent(m_tint) : std::string("none")) << std::endl
            << "]";
        return oss.str();
    }

    MI_DECLARE_CLASS(LacquerBSDF)

private:
    /// eval (f_r * cos) and/or pdf; `si.wi` is Lacquer's wo, `wo` Lacquer's wi.
    std::pair<Spectrum, Float> eval_pdf_impl(const SurfaceInteraction3f &si, const Vector3f &wo,
                                             Mask active, bool want_f, bool want_pdf) const {
        if constexpr (!dr::is_jit_v<Float>) {
            if (!active)
                return { 0.f, 0.f };
            float a[3] = { wo.x(), wo.y(), wo.z() }, b[3] = { si.wi.x(), si.wi.y(), si.wi.z() };
            float f[3] = { 0.f, 0.f, 0.f }, pdf = 0.f;
            lq_material *m = m_material.get();
            if (use_footprint(si)) {
                float uv[2], duv[4];
                spatial_inputs(si, uv, duv);
                if (want_f && want_pdf)
                    lacquer_detail::check(lq_eval_pdf_spatial(m, 1, a, b, uv, duv, f, &pdf), "lq_eval_pdf_spatial");
                else if (want_f)
                    lacquer_detail::check(lq_eval_spatial(m, 1, a, b, uv, duv, f), "lq_eval_spatial");
                else
                    lacquer_detail::check(lq_pdf_spatial(m, 1, a, b, uv, duv, &pdf), "lq_pdf_spatial");
            } else {
                if (want_f && want_pdf)
                    lacquer_detail::check(lq_eval_pdf_one(m, a, b, f, &pdf), "lq_eval_pdf_one");
                else if (want_f)
                    lacquer_detail::check(lq_eval_one(m, a, b, f), "lq_eval_one");
                else
                    lacquer_detail::check(lq_pdf_one(m, a, b, &pdf), "lq_pdf_one");
            }
            UnpolarizedSpectrum value(0.f);
            if (want_f) {
                float cos_l = std::max(wo.z(), 0.f);
                value = from_rgb(f, si) * cos_l;
                if (m_tint)
                    value *= m_tint->eval(si, active);
            }
            return { depolarizer<Spectrum>(value), pdf };
        } else {
            size_t n = batch_begin("eval/pdf", si.wi, wo, active);
            Float uv_b, duv_b;
            bool spatial = batch_spatial(si, n, uv_b, duv_b);
            if (!spatial) {
                // Structure of arrays, in place (see sample()): Lacquer's wi is Mitsuba's wo.
                FloatJ ax = lanes(wo.x(), n), ay = lanes(wo.y(), n), az = lanes(wo.z(), n),
                       bx = lanes(si.wi.x(), n), by = lanes(si.wi.y(), n), bz = lanes(si.wi.z(), n);
                MaskJ act = lanes(active, n);
                FloatJ f_r, f_g, f_b, pdf_j;
                if (want_f) {
                    f_r = outputs<FloatJ>(n);
                    f_g = outputs<FloatJ>(n);
                    f_b = outputs<FloatJ>(n);
                }
                if (want_pdf)
                    pdf_j = outputs<FloatJ>(n);
                dr::eval(ax, ay, az, bx, by, bz, act);
                const float *pax = ax.data(), *pay = ay.data(), *paz = az.data(),
                            *pbx = bx.data(), *pby = by.data(), *pbz = bz.data();
                const uint8_t *pa = mask_bytes(act);
                float *pr = want_f ? f_r.data() : nullptr, *pg = want_f ? f_g.data() : nullptr,
                      *pb = want_f ? f_b.data() : nullptr, *pp = want_pdf ? pdf_j.data() : nullptr;
                dr::sync_thread();
                lq_material *m = m_material.get();
                if (want_f && want_pdf)
                    lacquer_detail::check(lq_eval_pdf_soa(m, n, pax, pay, paz, pbx, pby, pbz, pa, pr, pg, pb, pp), "lq_eval_pdf_soa");
                else if (want_f)
                    lacquer_detail::check(lq_eval_soa(m, n, pax, pay, paz, pbx, pby, pbz, pa, pr, pg, pb), "lq_eval_soa");
                else
                    lacquer_detail::check(lq_pdf_soa(m, n, pax, pay, paz, pbx, pby, pbz, pa, pp), "lq_pdf_soa");
                Spectrum value(0.f);
                Float pdf_v(0.f);
                if (want_f) {
                    UnpolarizedSpectrum v = UnpolarizedSpectrum(Float(f_r), Float(f_g), Float(f_b)) * dr::maximum(wo.z(), 0.f);
                    if (m_tint)
                        v *= m_tint->eval(si, active);
                    value = depolarizer<Spectrum>(v) & active;
                }
                if (want_pdf)
                    pdf_v = dr::select(active, Float(pdf_j), 0.f);
                return { value, pdf_v };
            }
            // Spatial (sparkle): interleaved arrays for the *_spatial calls.
            Float a_b = interleave(n, { wo.x(), wo.y(), wo.z() });
            Float b_b = interleave(n, { si.wi.x(), si.wi.y(), si.wi.z() });
            const float *a = host(a_b), *b = host(b_b);
            const float *uv = spatial ? host(uv_b) : nullptr, *duv = spatial ? host(duv_b) : nullptr;
            std::vector<float> f(want_f ? 3 * n : 0), pdf(want_pdf ? n : 0);
            lq_material *m = m_material.get();
            if (want_f && want_pdf)
                lacquer_detail::check(lq_eval_pdf_spatial(m, n, a, b, uv, duv, f.data(), pdf.data()), "lq_eval_pdf_spatial");
            else if (want_f)
                lacquer_detail::check(lq_eval_spatial(m, n, a, b, uv, duv, f.data()), "lq_eval_spatial");
            else
                lacquer_detail::check(lq_pdf_spatial(m, n, a, b, uv, duv, pdf.data()), "lq_pdf_spatial");
            Spectrum value(0.f);
            Float pdf_v(0.f);
            if (want_f) {
                Vector3f fv = deinterleave3(f, n);
                UnpolarizedSpectrum v = UnpolarizedSpectrum(fv.x(), fv.y(), fv.z()) * dr::maximum(wo.z(), 0.f);
                if (m_tint)
                    v *= m_tint->eval(si, active);
                value = depolarizer<Spectrum>(v) & active;
            }
            if (want_pdf)
                pdf_v = dr::select(active, dr::load<Float>(pdf.data(), n), 0.f);
            return { value, pdf_v };
        }
    }

    /// Lacquer RGB (linear Rec.709) to this variant's spectrum type.
    UnpolarizedSpectrum from_rgb(const float *rgb, const SurfaceInteraction3f &si) const {
        if constexpr (is_rgb_v<Spectrum>) {
            DRJIT_MARK_USED(si);
            return UnpolarizedSpectrum(rgb[0], rgb[1], rgb[2]);
        } else if constexpr (is_monochromatic_v<Spectrum>) {
            DRJIT_MARK_USED(si);
            return UnpolarizedSpectrum(0.2126f * rgb[0] + 0.7152f * rgb[1] + 0.0722f * rgb[2]);
        } else {
            // Mitsuba's own RGB upsampling (valid on [0, 1]); values above 1 (f_r, weights) are
            // scaled into range first and the spectrum scaled back.
            float scale = std::max({ rgb[0], rgb[1], rgb[2] });
            if (!(scale > 0.f))
                return UnpolarizedSpectrum(0.f);
            Color<float, 3> c(rgb[0] / scale, rgb[1] / scale, rgb[2] / scale);
            auto coeff = srgb_model_fetch(c);
            return scale * srgb_model_eval<UnpolarizedSpectrum>(coeff, si.wavelengths);
        }
    }

    /// Scalar variants: true when uv and a footprint should be passed for this interaction.
    bool use_footprint(const SurfaceInteraction3f &si) const {
        if constexpr (!dr::is_jit_v<Float>)
            return m_spatial && si.has_uv_partials();
        else
            return false;
    }

    void spatial_inputs(const SurfaceInteraction3f &si, float *uv, float *duv) const {
        if constexpr (!dr::is_jit_v<Float>) {
            uv[0] = si.uv.x(); uv[1] = si.uv.y();
            duv[0] = si.duv_dx.x(); duv[1] = si.duv_dx.y();
            duv[2] = si.duv_dy.x(); duv[3] = si.duv_dy.y();
        }
    }

    // ---- JIT variants: the batched path -------------------------------------------------

    template <typename... Ts>
    size_t batch_begin(const char *what, const Ts &...values) const {
        if (jit_flag(JitFlag::SymbolicScope))
            Throw("lacquer: %s was called inside a symbolic Dr.Jit scope. The lacquer plugin calls "
                  "the Lacquer C library on evaluated arrays and cannot run inside symbolic loops "
                  "or calls: render in wavefront mode with "
                  "dr.set_flag(dr.JitFlag.SymbolicLoops, False) and "
                  "dr.set_flag(dr.JitFlag.SymbolicCalls, False) (see docs/mitsuba.md).", what);
        size_t n = 1;
        ((n = std::max(n, (size_t) dr::width(values))), ...);
        return n;
    }

    using FloatJ = dr::detached_t<Float>;
    using UInt32J = dr::detached_t<UInt32>;
    using MaskJ = dr::detached_t<Mask>;

    /// A detached array of width n (width-1 operands broadcast), for a structure-of-arrays
    /// call; evaluate it (dr::eval) before taking .data(). Already evaluated arrays of width n
    /// are used in place (no copy).
    template <typename T>
    static dr::detached_t<T> lanes(const T &v, size_t n) {
        dr::detached_t<T> d = dr::detach<false>(v);
        if (dr::width(d) != n)
            d.resize(n);
        return d;
    }

    /// An uninitialised array of n elements for the library to write into (allocated by .data()).
    template <typename T>
    static T outputs(size_t n) { return dr::empty<T>(n); }

    /// The bytes of an evaluated LLVM mask: Dr.Jit stores a Bool lane as one byte, 0 or 1
    /// (the layout lq_*_soa take as `active`).
    static const uint8_t *mask_bytes(MaskJ &m) {
        static_assert(sizeof(bool) == 1, "Dr.Jit LLVM masks are one byte per lane");
        return reinterpret_cast<const uint8_t *>(m.data());
    }

    /// Interleaves k arrays (width n or 1) into one evaluated array of k*n values.
    static Float interleave(size_t n, std::initializer_list<Float> comps) {
        size_t k = comps.size();
        Float buf = dr::zeros<Float>(k * n);
        UInt32 idx = dr::arange<UInt32>((uint32_t) n) * (uint32_t) k;
        uint32_t j = 0;
        for (const Float &c : comps)
            dr::scatter(buf, dr::detach(c), idx + j++);
        dr::eval(buf);
        return buf;
    }

    /// Host pointer to an evaluated LLVM array (waits for the kernels that produce it).
    static const float *host(Float &a) {
        const float *p = a.data();
        dr::sync_thread();
        return p;
    }

    static Vector3f deinterleave3(const std::vector<float> &v, size_t n) {
        Float all = dr::load<Float>(v.data(), 3 * n);
        UInt32 idx = dr::arange<UInt32>((uint32_t) n) * 3u;
        return Vector3f(dr::gather<Float>(all, idx), dr::gather<Float>(all, idx + 1u),
                        dr::gather<Float>(all, idx + 2u));
    }

    /// uv and footprints of a batch. Lanes without ray differentials (zero partials, e.g.
    /// secondary bounces) get an effectively infinite footprint: the contract's mean lobe,
    /// as the scalar path gives them by calling the functions without uv.
    bool batch_spatial(const SurfaceInteraction3f &si, size_t n, Float &uv, Float &duv) const {
        if (!m_spatial || !si.has_uv_partials())
            return false;
        Mask has = dr::any(si.duv_dx != 0.f) || dr::any(si.duv_dy != 0.f);
        if (dr::none_or<false>(has))
            return false;
        const float huge = 1e6f;
        uv = interleave(n, { si.uv.x(), si.uv.y() });
        duv = interleave(n, { dr::select(has, si.duv_dx.x(), huge), dr::select(has, si.duv_dx.y(), 0.f),
                              dr::select(has, si.duv_dy.x(), 0.f), dr::select(has, si.duv_dy.y(), huge) });
        return true;
    }

    /// True when the material samples a Dirac lobe (smooth clearcoat): sampled over a grid of
    /// lobe numbers and view angles (the mirror lobe is selected in proportion to the coat's
    /// Fresnel reflectance, large at grazing angles).
    bool probe_delta() const {
        const int nu = 32;
        const float cosines[] = { 1.f, 0.5f, 0.1f, 0.02f };
        for (float c : cosines) {
            float wo[3] = { std::sqrt(std::max(0.f, 1.f - c * c)), 0.f, c };
            for (int i = 0; i < nu; ++i) {
                float u[3] = { (i + 0.5f) / nu, 0.37f, 0.61f }, wi[3], w[3], pdf;
                uint32_t flags = 0;
                lacquer_detail::check(lq_sample_one(m_material.get(), wo, u, wi, w, &pdf, &flags),
                                      "lq_sample_one");
                if (flags & LQ_SAMPLE_DELTA)
                    return true;
            }
        }
        return false;
    }

    lacquer_detail::MaterialPtr m_material;
    std::string m_json, m_model;
    ref<Texture> m_tint;
    bool m_spatial = false, m_has_delta = false;
    uint32_t m_smooth_type = 0;

    MI_TRAVERSE_CB(Base, m_tint)
};

NAMESPACE_END(mitsuba)

// Registers only the variants this plugin supports (MI_EXPORT_PLUGIN would instantiate all
// thirteen, including polarized and CUDA ones that make no sense for an RGB C library).
extern "C" MI_EXPORT void init_plugin(std::string_view name, mitsuba::PluginRegisterFn fn) {
    using namespace mitsuba;
    fn(name, "scalar_rgb", ObjectType::BSDF, [](void *, const Properties &p) -> ref<Object> {
        return new LacquerBSDF<float, Color<float, 3>>(p);
    });
    fn(name, "scalar_spectral", ObjectType::BSDF, [](void *, const Properties &p) -> ref<Object> {
        return new LacquerBSDF<float, Spectrum<float, 4>>(p);
    });
#if defined(LACQUER_WITH_LLVM)
    using FloatL = dr::DiffArray<JitBackend::LLVM, float>;
    fn(name, "llvm_ad_rgb", ObjectType::BSDF, [](void *, const Properties &p) -> ref<Object> {
        return new LacquerBSDF<FloatL, Color<FloatL, 3>>(p);
    });
#endif
}
