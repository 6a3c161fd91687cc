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
//   components of a split material            lq_material_lobe_part: one per lobe group
//     (coated_paint, untextured; RGB path)    (pigment: Diffuse, flakes/metal base: Glossy,
//                                             coat: Glossy or DeltaReflection); ctx.type_mask /
//                                             ctx.component -> a lobe mask for the *_lobes calls
//                                             (every component enabled: the plain calls)
//   otherwise component 0: the smooth lobes   lq_material_lobes: LQ_LOBE_DIFFUSE / _GLOSSY
//                                             (+ Anisotropic for LQ_LOBE_ANISOTROPIC)
//   component 1 (or 0): the mirror lobe       LQ_LOBE_DELTA; LQ_SAMPLE_DELTA samples
//   NonSymmetric, SpatiallyVarying flags      LQ_LOBE_NON_RECIPROCAL, _SPATIALLY_VARYING
//   eval_diffuse_reflectance                  lq_material_diffuse_reflectance (pigment albedo)
//
// Variants: scalar_rgb, scalar_spectral (materials with spectral physics, LQ_LOBE_SPECTRAL:
// evaluated by the core at the ray's wavelengths, lq_eval_spectral / lq_sample_spectral; the
// others: the RGB result upsampled per evaluation with Mitsuba's own sRGB model, Jakob &
// Hanika 2019, scaled for values above 1), llvm_ad_rgb and llvm_ad_spectral
// (batched: the arrays are evaluated, one C ABI call per method call; without a sparkle footprint
// the structure-of-arrays calls lq_*_soa read the component arrays and mask bytes in place and
// write into Dr.Jit arrays that become the results; this works only in wavefront mode, i.e.
// with dr.JitFlag.SymbolicLoops and SymbolicCalls off; traced symbolically the plugin returns
// zero / an invalid sample and warns once per object, see symbolic_scope()). llvm_ad_spectral
// follows scalar_spectral: LQ_LOBE_SPECTRAL materials through lq_eval_spectral /
// lq_sample_spectral on the active lanes with their four wavelengths (packed on the host, run
// in blocks on Dr.Jit's thread pool), every other material through the RGB batched path with
// the result upsampled per lane as scalar_spectral upsamples it.
//
// Parameters (see docs/mitsuba.md):
//   model      string   a Lacquer model name (`lacquer models`), e.g. "coated_paint"
//   preset     string   a Lacquer preset name (`lacquer presets`)
//   material   string   Lacquer material JSON, e.g. {"model": "lambert", "albedo": 0.8}
//                       (exactly one of model / preset / material)
//   <any parameter of the model>   typed: <float>/<integer> for scalars, <rgb> (or <float>,
//                       grey) for colours, <boolean> for flags, <string> for choices, text
//                       and JSON-valued parameters; overrides the preset's / JSON's value.
//                       Names, kinds and ranges come from the core (lq_model_param), so the
//                       plugin holds no parameter list. Every scalar and colour parameter is
//                       in mi.traverse; parameters_changed rebuilds the material (a bad value
//                       raises and keeps the previous material).
//   base_color, flake_density, coat_roughness (coated_paint)   also any Mitsuba texture:
//                       evaluated per lane and passed to lq_eval_pdf_varying /
//                       lq_sample_varying (mean lobe, no sparkle); a constant texture is
//                       the plain value; untextured materials keep the plain calls
//   tint       texture  optional reflectance-like multiplier in [0, 1] (e.g. a bitmap): scales
//                       f_r, and so the sample weight; the pdf is unchanged
//   footprint  bool     pass uv and the ray-differential footprint to spatially varying
//                       materials (sparkle); default true

#include <mitsuba/core/properties.h>
#include <mitsuba/core/string.h>
#include <mitsuba/render/bsdf.h>
#include <mitsuba/render/srgb.h>
#include <mitsuba/render/texture.h>
#include <nanothread/nanothread.h>

#include <lacquer.h>

#include <algorithm>
#include <atomic>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
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

/// A model parameter as the core describes it (lq_model_param).
struct ParamInfo {
    std::string name, unit, choices, doc;
    int32_t kind = 0;
    double min = 0, max = 0;

    bool numeric() const { return kind == LQ_PARAM_SCALAR || kind == LQ_PARAM_INTEGER; }
    bool color() const { return kind == LQ_PARAM_COLOR; }
    /// "[0, 100] %" / "one of Al, Au" / "true or false": what the error messages show.
    std::string range() const {
        char buf[96];
        switch (kind) {
            case LQ_PARAM_SCALAR:
            case LQ_PARAM_INTEGER:
            case LQ_PARAM_COLOR:
                std::snprintf(buf, sizeof buf, "[%g, %g]", min, max);
                return std::string(buf) + (unit.empty() ? "" : " " + unit) +
                       (kind == LQ_PARAM_COLOR ? " per component" : "") +
                       (kind == LQ_PARAM_INTEGER ? " (whole numbers)" : "");
            case LQ_PARAM_BOOL: return "true or false";
            case LQ_PARAM_CHOICE: {
                std::string c = choices;
                std::replace(c.begin(), c.end(), '|', ',');
                return "one of " + c;
            }
            case LQ_PARAM_JSON: return "JSON text";
            default: return "a string";
        }
    }
    const char *xml_tag() const {
        switch (kind) {
            case LQ_PARAM_SCALAR: return "<float>";
            case LQ_PARAM_INTEGER: return "<integer> or <float>";
            case LQ_PARAM_COLOR: return "<rgb> or <float>";
            case LQ_PARAM_BOOL: return "<boolean>";
            default: return "<string>";
        }
    }
};

/// The parameters of a model, from the core.
inline std::vector<ParamInfo> model_params(const std::string &model) {
    size_t n = 0;
    lq_status s = lq_model_param_count(model.c_str(), &n);
    if (s != LQ_OK)
        Throw("lacquer: unknown model \"%s\" (%s): %s", model, lq_status_name(s), lq_last_error());
    std::vector<ParamInfo> out(n);
    for (size_t i = 0; i < n; ++i) {
        lq_param_spec spec;
        check(lq_model_param(model.c_str(), i, &spec), "lq_model_param");
        out[i].name = spec.name;
        out[i].unit = spec.unit;
        out[i].choices = spec.choices;
        out[i].doc = spec.doc;
        out[i].kind = spec.kind;
        out[i].min = spec.min;
        out[i].max = spec.max;
    }
    return out;
}

/// One parameter's value as JSON text (lq_material_param_json).
inline std::string param_json(const lq_material *m, const std::string &name) {
    char *text = nullptr;
    check(lq_material_param_json(m, name.c_str(), &text), "lq_material_param_json");
    std::string out = text;
    lq_string_free(text);
    return out;
}

/// A JSON string literal.
inline std::string json_string(const std::string &s) {
    std::string out = "\"";
    for (char c : s) {
        if (c == '"' || c == '\\') {
            out += '\\';
            out += c;
        } else if ((unsigned char) c < 0x20) {
            char buf[8];
            std::snprintf(buf, sizeof buf, "\\u%04x", c);
            out += buf;
        } else {
            out += c;
        }
    }
    return out + "\"";
}

/// The content of a JSON string literal without escapes (model names, choices).
inline std::string unquote(const std::string &s) {
    return s.size() >= 2 && s.front() == '"' ? s.substr(1, s.size() - 2) : s;
}

/// A number as JSON (exact for doubles; whole numbers without a fraction, for integers).
inline std::string json_number(double v) {
    if (!std::isfinite(v))
        return "null"; // the core rejects it with the parameter's name and range
    char buf[40];
    if (v == std::floor(v) && std::fabs(v) < 1e15)
        std::snprintf(buf, sizeof buf, "%.0f", v);
    else
        std::snprintf(buf, sizeof buf, "%.17g", v);
    return buf;
}

/// A float32 value as JSON: the shortest decimal that reads back as the same float.
inline std::string json_float(double v) {
    float f = (float) v;
    if (!std::isfinite(f))
        return "null";
    char buf[32];
    auto r = std::to_chars(buf, buf + sizeof buf, f);
    return std::string(buf, r.ptr);
}

/// Numbers of a canonical JSON value: `0.5` -> {0.5}, `[0.1,0.2,0.3]` -> {0.1, 0.2, 0.3},
/// `true` -> {1}.
inline std::vector<double> json_numbers(const std::string &text) {
    std::vector<double> out;
    if (text == "true" || text == "false")
        return { text == "true" ? 1.0 : 0.0 };
    const char *p = text.c_str();
    while (*p) {
        if ((*p >= '0' && *p <= '9') || *p == '-' || *p == '.') {
            char *end = nullptr;
            out.push_back(std::strtod(p, &end));
            p = end;
        } else {
            ++p;
        }
    }
    return out;
}

} // namespace lacquer_detail

template <typename Float, typename Spectrum>
class LacquerBSDF final : public BSDF<Float, Spectrum> {
public:
    MI_IMPORT_BASE(BSDF, m_flags, m_components)
    MI_IMPORT_TYPES(Texture)

    LacquerBSDF(const Properties &props) : Base(props) {
        using namespace lacquer_detail;
        int sources = (int) props.has_property("material") + (int) props.has_property("preset") +
                      (int) props.has_property("model");
        if (sources != 1)
            Throw("lacquer: give exactly one of \"model\" (a name from `lacquer models`, e.g. "
                  "<string name=\"model\" value=\"coated_paint\"/>), \"preset\" (a name from "
                  "`lacquer presets`) or \"material\" (material JSON, e.g. {\"model\": \"lambert\"}); "
                  "typed parameters then override its values");

        // 1. The starting material: JSON, a preset or a model's defaults.
        lq_material *raw = nullptr;
        lq_status s;
        const char *what;
        if (props.has_property("material")) {
            what = "material";
            s = lq_material_from_json(props.get<std::string>("material").c_str(), &raw);
        } else if (props.has_property("preset")) {
            what = "preset";
            s = lq_material_from_preset(props.get<std::string>("preset").c_str(), &raw);
        } else {
            what = "model";
            std::string json = "{\"model\": " + json_string(props.get<std::string>("model")) + "}";
            s = lq_material_from_json(json.c_str(), &raw);
        }
        if (s != LQ_OK)
            Throw("lacquer: invalid \"%s\" (%s): %s", what, lq_status_name(s), lq_last_error());
        MaterialPtr start(raw, MaterialDeleter());

        // 2. Its model's parameters (names, kinds, ranges from the core) and current values.
        m_model = unquote(param_json(raw, "model"));
        m_params = model_params(m_model);
        m_values.resize(m_params.size());
        for (size_t i = 0; i < m_params.size(); ++i)
            m_values[i] = param_json(raw, m_params[i].name);

        // 3. Typed properties override those values; a texture on base_color, flake_density
        //    or coat_roughness (coated_paint) is evaluated per lane and passed to the core's
        //    per-element calls (lq_eval_pdf_varying / lq_sample_varying).
        for (const auto &it : props) {
            std::string key(it.name());
            if (key == "material" || key == "preset" || key == "model" || key == "tint" ||
                key == "footprint")
                continue;
            size_t i = find_param(key);
            if (it.type() == Properties::Type::Object && set_texture(props, key, i))
                continue;
            m_values[i] = property_value(props, m_params[i], key, it.type());
        }
        if (m_tex_roughness) {
            // The per-element calls need a rough coat (elements in [0.001, 0.5]); the
            // material's own value then only decides the flags, so a smooth coat (0: a delta
            // lobe) becomes the smallest rough one.
            size_t i = find_param("coat_roughness");
            std::vector<double> v = json_numbers(m_values[i]);
            if (v.size() == 1 && v[0] < 0.001)
                m_values[i] = "0.001";
        }
        std::string error;
        if (!rebuild(m_values, error))
            Throw("lacquer: invalid property for model \"%s\": %s", m_model, error);

        // 4. Every scalar and colour parameter as a traversable value.
        m_scalar.resize(m_params.size(), Float(0.f));
        m_color.resize(m_params.size(), Color3f(0.f));
        store_slots();

        if (props.has_property("tint"))
            m_tint = props.get_texture<Texture>("tint", 1.f);
        m_footprint = props.get<bool>("footprint", true);
        update_flags();
    }

    /// The texture of a textured parameter, or null.
    const ref<Texture> &texture_of(const std::string &name) const {
        static const ref<Texture> none;
        if (name == "base_color")
            return m_tex_color;
        if (name == "flake_density")
            return m_tex_density;
        if (name == "coat_roughness")
            return m_tex_roughness;
        return none;
    }

    /// The texture member of a texturable parameter (null for the others).
    ref<Texture> *texture_slot(const std::string &name) {
        if (name == "base_color")
            return &m_tex_color;
        if (name == "flake_density")
            return &m_tex_density;
        if (name == "coat_roughness")
            return &m_tex_roughness;
        return nullptr;
    }

    /// True when any paint parameter is textured (the per-element calls are used).
    bool textured() const { return m_tex_color || m_tex_density || m_tex_roughness; }

    /// Every scalar and colour parameter of the model (non-differentiable: editing one
    /// rebuilds the material in parameters_changed), the textures of textured parameters in
    /// their place (their own parameters, e.g. `base_color.data`, are read per lane: editing
    /// them needs no rebuild), plus the tint texture.
    void traverse(TraversalCallback *cb) override {
        for (size_t i = 0; i < m_params.size(); ++i) {
            if (ref<Texture> *t = texture_slot(m_params[i].name); t && *t)
                cb->put(m_params[i].name, *t, ParamFlags::NonDifferentiable);
            else if (m_params[i].numeric())
                cb->put(m_params[i].name, m_scalar[i], ParamFlags::NonDifferentiable);
            else if (m_params[i].color())
                cb->put(m_params[i].name, m_color[i], ParamFlags::NonDifferentiable);
        }
        if (m_tint)
            cb->put("tint", m_tint, ParamFlags::NonDifferentiable);
    }

    /// Rebuilds the material from the traversed values. An invalid value (out of range, NaN,
    /// an impossible combination) raises a Mitsuba error naming the parameter and its range;
    /// the previous material and the previous values stay in place.
    void parameters_changed(const std::vector<std::string> &keys) override {
        // A traversed value is a float32 copy: a slot still equal to the float32 of the value
        // in use keeps that value exactly (editing one parameter must not round the others).
        std::vector<std::string> values = m_values;
        for (size_t i = 0; i < m_params.size(); ++i) {
            if (texture_of(m_params[i].name))
                continue; // its value in the material only sets the flags
            std::vector<double> now = lacquer_detail::json_numbers(m_values[i]);
            if (m_params[i].numeric()) {
                double v = scalar_of(m_scalar[i]);
                if (!(now.size() == 1 && (double) (float) now[0] == v))
                    values[i] = lacquer_detail::json_number(v);
            } else if (m_params[i].color()) {
                if (now.size() == 1)
                    now = { now[0], now[0], now[0] };
                double c[3] = { scalar_of(m_color[i].x()), scalar_of(m_color[i].y()), scalar_of(m_color[i].z()) };
                bool same = now.size() == 3;
                for (int k = 0; k < 3 && same; ++k)
                    same = (double) (float) now[k] == c[k];
                if (!same)
                    values[i] = "[" + lacquer_detail::json_number(c[0]) + "," + lacquer_detail::json_number(c[1]) +
                                "," + lacquer_detail::json_number(c[2]) + "]";
            }
        }
        std::string error;
        if (values != m_values) {
            if (!rebuild(values, error)) {
                store_slots(); // back to the values of the material in use
                std::string changed;
                for (const std::string &k : keys)
                    changed += (changed.empty() ? "" : ", ") + k;
                Throw("lacquer: invalid parameter value (%s) for model \"%s\": %s. The previous "
                      "material is kept.", changed.empty() ? std::string("?") : changed, m_model, error);
            }
            m_values = values;
            update_flags();
        }
        Base::parameters_changed(keys);
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
        // Split materials (one component per lobe group): the context's lobe mask; kAllLobes
        // (the plain calls) when every component is enabled.
        uint32_t lobes = kAllLobes;
        bool smooth_on, delta_on;
        if (m_split) {
            lobes = context_lobes(ctx);
            if (lobes == 0)
                return { bs, 0.f };
            if (lobes == m_all_lobes)
                lobes = kAllLobes;
            smooth_on = delta_on = true;
        } else {
            smooth_on = smooth_enabled(ctx);
            delta_on = m_has_delta && ctx.is_enabled(BSDFFlags::DeltaReflection, m_delta_component);
        }
        if (!smooth_on && !delta_on)
            return { bs, 0.f };
        // The type and component of a non-delta sample (split: of the enabled groups).
        uint32_t nd_type = m_smooth_sampled, nd_comp = 0;
        if (m_split)
            nondelta_component(lobes == kAllLobes ? m_all_lobes : lobes, nd_type, nd_comp);

        if constexpr (!dr::is_jit_v<Float>) {
            if (!active)
                return { bs, 0.f };
            if constexpr (is_spectral_v<Spectrum>)
                if (m_lobes & LQ_LOBE_SPECTRAL)
                    return sample_spectral(si, sample1, sample2, smooth_on, delta_on, active);
            float wo[3] = { si.wi.x(), si.wi.y(), si.wi.z() },
                  u[3] = { sample1, sample2.x(), sample2.y() }, wi[3], weight[3], pdf;
            uint32_t flags = 0;
            if (lobes != kAllLobes) {
                // Some components only (split, untextured, RGB): the lobe calls.
                if (use_footprint(si)) {
                    float uv[2], duv[4];
                    spatial_inputs(si, uv, duv);
                    lacquer_detail::check(lq_sample_lobes(m_material.get(), 1, wo, u, uv, duv, lobes, wi,
                                                          weight, &pdf, &flags),
                                          "lq_sample_lobes");
                } else {
                    lacquer_detail::check(
                        lq_sample_one_lobes(m_material.get(), wo, u, lobes, wi, weight, &pdf, &flags),
                        "lq_sample_one_lobes");
                }
            } else if (textured()) {
                TexLane t;
                texture_values(si, active, t);
                check_varying(lq_sample_varying(m_material.get(), 1, &wo[0], &wo[1], &wo[2], &u[0], &u[1],
                                                &u[2], t.r(), t.g(), t.b(), t.d(), t.a(), nullptr, &wi[0],
                                                &wi[1], &wi[2], &weight[0], &weight[1], &weight[2], &pdf,
                                                &flags),
                              "lq_sample_varying");
            } else if (use_footprint(si)) {
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
            bs.sampled_type = delta ? +BSDFFlags::DeltaReflection : nd_type;
            bs.sampled_component = delta ? m_delta_component : nd_comp;
            UnpolarizedSpectrum value = from_rgb(weight, si);
            if (m_tint)
                value *= m_tint->eval(si, active);
            return { bs, depolarizer<Spectrum>(value) };
        } else {
            if (symbolic_scope())
                return { bs, 0.f }; // invalid sample: pdf 0, value 0
            size_t n = batch_width(si.wi, sample1, sample2, active);
            Float uv_b, duv_b;
            bool spatial = batch_spatial(si, n, uv_b, duv_b);
            if constexpr (is_spectral_v<Spectrum>)
                if (m_lobes & LQ_LOBE_SPECTRAL)
                    return sample_spectral_lanes(si, sample1, sample2, smooth_on, delta_on, active, n,
                                                 spatial, uv_b, duv_b);
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
                FloatJ tex[5];
                const float *tp[5] = { nullptr, nullptr, nullptr, nullptr, nullptr };
                if (textured())
                    texture_lanes(si, active, n, tex, tp);
                dr::sync_thread();
                if (lobes != kAllLobes)
                    lacquer_detail::check(lq_sample_soa_lobes(m_material.get(), n, px, py, pz, p0, p1, p2, pa,
                                                              lobes, o[0], o[1], o[2], o[3], o[4], o[5], o[6],
                                                              of),
                                          "lq_sample_soa_lobes");
                else if (textured())
                    check_varying(lq_sample_varying(m_material.get(), n, px, py, pz, p0, p1, p2, tp[0], tp[1],
                                                    tp[2], tp[3], tp[4], pa, o[0], o[1], o[2], o[3], o[4],
                                                    o[5], o[6], of),
                                  "lq_sample_varying");
                else
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
                bs.sampled_type = dr::select(delta, UInt32(+BSDFFlags::DeltaReflection), UInt32(nd_type));
                bs.sampled_component = dr::select(delta, UInt32(m_delta_component), UInt32(nd_comp));
                UnpolarizedSpectrum value = rgb_lanes(w_r, w_g, w_b, si);
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
            if (lobes != kAllLobes)
                lacquer_detail::check(
                    lq_sample_lobes(m_material.get(), n, wo_p, u_p, spatial ? host(uv_b) : nullptr,
                                    spatial ? host(duv_b) : nullptr, lobes, wi.data(), weight.data(),
                                    pdf.data(), flags.data()),
                    "lq_sample_lobes");
            else
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
            bs.sampled_type = dr::select(delta, UInt32(+BSDFFlags::DeltaReflection), UInt32(nd_type));
            bs.sampled_component = dr::select(delta, UInt32(m_delta_component), UInt32(nd_comp));
            UnpolarizedSpectrum value = rgb_interleaved(weight, n, si);
            if (m_tint)
                value *= m_tint->eval(si, active);
            return { bs, depolarizer<Spectrum>(value) & ok };
        }
    }

    Spectrum eval(const BSDFContext &ctx, const SurfaceInteraction3f &si, const Vector3f &wo,
                  Mask active) const override {
        MI_MASKED_FUNCTION(ProfilerPhase::BSDFEvaluate, active);
        uint32_t lobes = eval_lobes(ctx);
        if (lobes == 0)
            return 0.f;
        return eval_pdf_impl(si, wo, active, true, false, lobes).first;
    }

    Float pdf(const BSDFContext &ctx, const SurfaceInteraction3f &si, const Vector3f &wo,
              Mask active) const override {
        MI_MASKED_FUNCTION(ProfilerPhase::BSDFEvaluate, active);
        uint32_t lobes = eval_lobes(ctx);
        if (lobes == 0)
            return 0.f;
        return eval_pdf_impl(si, wo, active, false, true, lobes).second;
    }

    std::pair<Spectrum, Float> eval_pdf(const BSDFContext &ctx, const SurfaceInteraction3f &si,
                                        const Vector3f &wo, Mask active) const override {
        MI_MASKED_FUNCTION(ProfilerPhase::BSDFEvaluate, active);
        uint32_t lobes = eval_lobes(ctx);
        if (lobes == 0)
            return { 0.f, 0.f };
        return eval_pdf_impl(si, wo, active, true, true, lobes);
    }

    /// The pigment / diffuse albedo from the core (lq_material_diffuse_reflectance), times
    /// the tint: no clearcoat highlight in albedo AOVs.
    Spectrum eval_diffuse_reflectance(const SurfaceInteraction3f &si, Mask active) const override {
        // coated_paint's diffuse reflectance is its base_color (the core's definition): a
        // textured one is the texture's value here.
        UnpolarizedSpectrum value = m_tex_color ? m_tex_color->eval(si, active) : from_rgb(m_diffuse, si);
        if (m_tint)
            value *= m_tint->eval(si, active);
        return depolarizer<Spectrum>(value) & active;
    }

    std::string to_string() const override {
        std::ostringstream oss;
        oss << "LacquerBSDF[" << std::endl
            << "  model = \"" << m_model << "\"," << std::endl
            << "  material = " << m_json << "," << std::endl
            << "  lobes = " << m_lobes << " (LQ_LOBE_* bits)," << std::endl
            << "  delta_lobe = " << (m_has_delta ? "true" : "false") << "," << std::endl
            << "  footprint = " << (m_spatial ? "true" : "false") << "," << std::endl
            << "  tint = " << (m_tint ? string::indent(m_tint) : std::string("none")) << "," << std::endl
            << "  base_color texture = " << (m_tex_color ? string::indent(m_tex_color) : std::string("none")) << "," << std::endl
            << "  flake_density texture = " << (m_tex_density ? string::indent(m_tex_density) : std::string("none")) << "," << std::endl
            << "  coat_roughness texture = " << (m_tex_roughness ? string::indent(m_tex_roughness) : std::string("none")) << std::endl
            << "]";
        return oss.str();
    }

    MI_DECLARE_CLASS(LacquerBSDF)

private:
    /// eval (f_r * cos) and/or pdf; `si.wi` is Lacquer's wo, `wo` Lacquer's wi.
    /// `lobes`: kAllLobes for the plain calls, else the lobe mask of the enabled components
    /// (split materials: untextured, RGB path) for the *_lobes calls.
    std::pair<Spectrum, Float> eval_pdf_impl(const SurfaceInteraction3f &si, const Vector3f &wo,
                                             Mask active, bool want_f, bool want_pdf,
                                             uint32_t lobes = kAllLobes) const {
        if constexpr (!dr::is_jit_v<Float>) {
            if (!active)
                return { 0.f, 0.f };
            if constexpr (is_spectral_v<Spectrum>)
                if (m_lobes & LQ_LOBE_SPECTRAL)
                    return eval_pdf_spectral(si, wo, active, want_f, want_pdf);
            float a[3] = { wo.x(), wo.y(), wo.z() }, b[3] = { si.wi.x(), si.wi.y(), si.wi.z() };
            float f[3] = { 0.f, 0.f, 0.f }, pdf = 0.f;
            lq_material *m = m_material.get();
            if (lobes != kAllLobes) {
                if (use_footprint(si)) {
                    float uv[2], duv[4];
                    spatial_inputs(si, uv, duv);
                    lacquer_detail::check(lq_eval_pdf_lobes(m, 1, a, b, uv, duv, lobes, want_f ? f : nullptr,
                                                            want_pdf ? &pdf : nullptr),
                                          "lq_eval_pdf_lobes");
                } else {
                    lacquer_detail::check(lq_eval_pdf_one_lobes(m, a, b, lobes, want_f ? f : nullptr,
                                                                want_pdf ? &pdf : nullptr),
                                          "lq_eval_pdf_one_lobes");
                }
            } else if (textured()) {
                TexLane t;
                texture_values(si, active, t);
                check_varying(lq_eval_pdf_varying(m, 1, &a[0], &a[1], &a[2], &b[0], &b[1], &b[2], t.r(), t.g(),
                                                  t.b(), t.d(), t.a(), nullptr, want_f ? &f[0] : nullptr,
                                                  want_f ? &f[1] : nullptr, want_f ? &f[2] : nullptr,
                                                  want_pdf ? &pdf : nullptr),
                              "lq_eval_pdf_varying");
            } else if (use_footprint(si)) {
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
            if (symbolic_scope())
                return { 0.f, 0.f };
            size_t n = batch_width(si.wi, wo, active);
            Float uv_b, duv_b;
            bool spatial = batch_spatial(si, n, uv_b, duv_b);
            if constexpr (is_spectral_v<Spectrum>)
                if (m_lobes & LQ_LOBE_SPECTRAL)
                    return eval_pdf_spectral_lanes(si, wo, active, n, spatial, uv_b, duv_b, want_f, want_pdf);
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
                FloatJ tex[5];
                const float *tp[5] = { nullptr, nullptr, nullptr, nullptr, nullptr };
                if (textured())
                    texture_lanes(si, active, n, tex, tp);
                dr::sync_thread();
                lq_material *m = m_material.get();
                if (lobes != kAllLobes)
                    lacquer_detail::check(lq_eval_pdf_soa_lobes(m, n, pax, pay, paz, pbx, pby, pbz, pa, lobes, pr,
                                                                pg, pb, pp),
                                          "lq_eval_pdf_soa_lobes");
                else if (textured())
                    check_varying(lq_eval_pdf_varying(m, n, pax, pay, paz, pbx, pby, pbz, tp[0], tp[1], tp[2],
                                                      tp[3], tp[4], pa, pr, pg, pb, pp),
                                  "lq_eval_pdf_varying");
                else if (want_f && want_pdf)
                    lacquer_detail::check(lq_eval_pdf_soa(m, n, pax, pay, paz, pbx, pby, pbz, pa, pr, pg, pb, pp), "lq_eval_pdf_soa");
                else if (want_f)
                    lacquer_detail::check(lq_eval_soa(m, n, pax, pay, paz, pbx, pby, pbz, pa, pr, pg, pb), "lq_eval_soa");
                else
                    lacquer_detail::check(lq_pdf_soa(m, n, pax, pay, paz, pbx, pby, pbz, pa, pp), "lq_pdf_soa");
                Spectrum value(0.f);
                Float pdf_v(0.f);
                if (want_f) {
                    UnpolarizedSpectrum v = rgb_lanes(f_r, f_g, f_b, si) * dr::maximum(wo.z(), 0.f);
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
            if (lobes != kAllLobes)
                lacquer_detail::check(lq_eval_pdf_lobes(m, n, a, b, uv, duv, lobes, want_f ? f.data() : nullptr,
                                                        want_pdf ? pdf.data() : nullptr),
                                      "lq_eval_pdf_lobes");
            else if (want_f && want_pdf)
                lacquer_detail::check(lq_eval_pdf_spatial(m, n, a, b, uv, duv, f.data(), pdf.data()), "lq_eval_pdf_spatial");
            else if (want_f)
                lacquer_detail::check(lq_eval_spatial(m, n, a, b, uv, duv, f.data()), "lq_eval_spatial");
            else
                lacquer_detail::check(lq_pdf_spatial(m, n, a, b, uv, duv, pdf.data()), "lq_pdf_spatial");
            Spectrum value(0.f);
            Float pdf_v(0.f);
            if (want_f) {
                UnpolarizedSpectrum v = rgb_interleaved(f, n, si) * dr::maximum(wo.z(), 0.f);
                if (m_tint)
                    v *= m_tint->eval(si, active);
                value = depolarizer<Spectrum>(v) & active;
            }
            if (want_pdf)
                pdf_v = dr::select(active, dr::load<Float>(pdf.data(), n), 0.f);
            return { value, pdf_v };
        }
    }

    // ---- scalar_spectral: materials with spectral physics (LQ_LOBE_SPECTRAL) ---------------
    // The core evaluates at the ray's four wavelengths (lq_eval_spectral / lq_sample_spectral):
    // the pearl paint's thin film and HTSG are not projected to RGB first. Other materials
    // keep the RGB path with Mitsuba's upsampling (from_rgb).

    /// The ray's wavelengths (nm) as the C ABI takes them.
    static void wavelengths_of(const SurfaceInteraction3f &si, float *lambda) {
        if constexpr (is_spectral_v<Spectrum> && !dr::is_jit_v<Float>) {
            for (size_t k = 0; k < 4; ++k)
                lambda[k] = si.wavelengths[k];
        } else {
            DRJIT_MARK_USED(si);
            DRJIT_MARK_USED(lambda);
        }
    }

    /// Four values at the ray's wavelengths as this variant's spectrum.
    static UnpolarizedSpectrum from_spectral(const float *v) {
        if constexpr (is_spectral_v<Spectrum> && !dr::is_jit_v<Float>)
            return UnpolarizedSpectrum(v[0], v[1], v[2], v[3]);
        else {
            DRJIT_MARK_USED(v);
            return UnpolarizedSpectrum(0.f);
        }
    }

    /// eval_pdf_impl of scalar_spectral for LQ_LOBE_SPECTRAL materials.
    std::pair<Spectrum, Float> eval_pdf_spectral(const SurfaceInteraction3f &si, const Vector3f &wo,
                                                 Mask active, bool want_f, bool want_pdf) const {
        float a[3] = { wo.x(), wo.y(), wo.z() }, b[3] = { si.wi.x(), si.wi.y(), si.wi.z() };
        float lambda[4], f[4] = { 0.f, 0.f, 0.f, 0.f }, pdf = 0.f;
        lq_material *m = m_material.get();
        wavelengths_of(si, lambda);
        bool footprint = use_footprint(si);
        float uv[2], duv[4];
        if (footprint)
            spatial_inputs(si, uv, duv);
        if (want_pdf)
            lacquer_detail::check(lq_pdf_one(m, a, b, &pdf), "lq_pdf_one");
        UnpolarizedSpectrum value(0.f);
        if (want_f) {
            lacquer_detail::check(lq_eval_spectral(m, 1, a, b, footprint ? uv : nullptr,
                                                   footprint ? duv : nullptr, lambda, f),
                                  "lq_eval_spectral");
            value = from_spectral(f) * std::max(wo.z(), 0.f);
            if (m_tint)
                value *= m_tint->eval(si, active);
        }
        return { depolarizer<Spectrum>(value), pdf };
    }

    /// sample() of scalar_spectral for LQ_LOBE_SPECTRAL materials.
    std::pair<BSDFSample3f, Spectrum> sample_spectral(const SurfaceInteraction3f &si, Float sample1,
                                                      const Point2f &sample2, bool smooth_on,
                                                      bool delta_on, Mask active) const {
        BSDFSample3f bs = dr::zeros<BSDFSample3f>();
        float wo[3] = { si.wi.x(), si.wi.y(), si.wi.z() },
              u[3] = { sample1, sample2.x(), sample2.y() }, wi[3], weight[4], pdf, lambda[4];
        uint32_t flags = 0;
        wavelengths_of(si, lambda);
        bool footprint = use_footprint(si);
        float uv[2], duv[4];
        if (footprint)
            spatial_inputs(si, uv, duv);
        lacquer_detail::check(lq_sample_spectral(m_material.get(), 1, wo, u, footprint ? uv : nullptr,
                                                 footprint ? duv : nullptr, lambda, wi, weight,
                                                 &pdf, &flags),
                              "lq_sample_spectral");
        bool delta = (flags & LQ_SAMPLE_DELTA) != 0;
        if ((flags & LQ_SAMPLE_FAILED) || !(pdf > 0.f) || (delta ? !delta_on : !smooth_on))
            return { bs, 0.f };
        bs.wo = Vector3f(wi[0], wi[1], wi[2]);
        bs.pdf = pdf;
        bs.eta = 1.f;
        bs.sampled_type = delta ? +BSDFFlags::DeltaReflection : m_smooth_sampled;
        bs.sampled_component = delta ? m_delta_component : 0u;
        UnpolarizedSpectrum value = from_spectral(weight);
        if (m_tint)
            value *= m_tint->eval(si, active);
        return { bs, depolarizer<Spectrum>(value) };
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

    using FloatJ = dr::detached_t<Float>;
    using UInt32J = dr::detached_t<UInt32>;
    using MaskJ = dr::detached_t<Mask>;

    // ---- Textured parameters (coated_paint: base_color, flake_density, coat_roughness) ---

    /// Scalar variants: the textured parameters at one interaction and the pointers the
    /// per-element calls take (NULL: not textured, the material's value).
    struct TexLane {
        float rgb[3] = { 0.f, 0.f, 0.f }, density = 0.f, roughness = 0.f;
        bool color = false, has_density = false, has_roughness = false;
        const float *r() const { return color ? &rgb[0] : nullptr; }
        const float *g() const { return color ? &rgb[1] : nullptr; }
        const float *b() const { return color ? &rgb[2] : nullptr; }
        const float *d() const { return has_density ? &density : nullptr; }
        const float *a() const { return has_roughness ? &roughness : nullptr; }
    };

    /// Evaluates the textures at `si` (scalar variants). base_color is RGB: Texture::eval in
    /// the RGB variants, Texture::eval_3 in scalar_spectral (a texture holding spectra there,
    /// e.g. a checkerboard or a non-raw bitmap, raises a Mitsuba error naming the limitation).
    void texture_values(const SurfaceInteraction3f &si, Mask active, TexLane &t) const {
        if constexpr (!dr::is_jit_v<Float>) {
            try {
                if (m_tex_color) {
                    Color3f c;
                    if constexpr (is_rgb_v<Spectrum>)
                        c = m_tex_color->eval(si, active);
                    else
                        c = m_tex_color->eval_3(si, active);
                    t.rgb[0] = c.x(); t.rgb[1] = c.y(); t.rgb[2] = c.z();
                    t.color = true;
                }
                if (m_tex_density) {
                    t.density = m_tex_density->eval_1(si, active);
                    t.has_density = true;
                }
                if (m_tex_roughness) {
                    t.roughness = m_tex_roughness->eval_1(si, active);
                    t.has_roughness = true;
                }
            } catch (const std::exception &e) {
                if constexpr (is_spectral_v<Spectrum>)
                    Throw("lacquer: a textured parameter could not be read as RGB / a float in this "
                          "spectral variant (the paint takes base_color as linear RGB: give a bitmap "
                          "with raw=\"true\", or render in scalar_rgb / llvm_ad_rgb): %s", e.what());
                throw;
            }
        } else {
            DRJIT_MARK_USED(si);
            DRJIT_MARK_USED(active);
            DRJIT_MARK_USED(t);
        }
    }

    /// JIT variants: the textured parameters as evaluated detached arrays of width n in
    /// `tex` (r, g, b, flake_density, coat_roughness) and their data pointers in `ptr`
    /// (untouched, NULL, for untextured ones). Waits for nothing: call dr::sync_thread()
    /// before the library reads them.
    void texture_lanes(const SurfaceInteraction3f &si, const Mask &active, size_t n, FloatJ (&tex)[5],
                       const float *(&ptr)[5]) const {
        if constexpr (dr::is_jit_v<Float>) {
            if (m_tex_color) {
                Color3f c;
                if constexpr (is_rgb_v<Spectrum>) {
                    c = m_tex_color->eval(si, active);
                } else {
                    // As in scalar_spectral: the paint takes base_color as RGB (eval_3).
                    try {
                        c = m_tex_color->eval_3(si, active);
                    } catch (const std::exception &e) {
                        Throw("lacquer: a textured parameter could not be read as RGB / a float in "
                              "this spectral variant (the paint takes base_color as linear RGB: give a "
                              "bitmap with raw=\"true\", or render in scalar_rgb / llvm_ad_rgb): %s",
                              e.what());
                    }
                }
                tex[0] = lanes(c.x(), n);
                tex[1] = lanes(c.y(), n);
                tex[2] = lanes(c.z(), n);
            }
            if (m_tex_density)
                tex[3] = lanes(m_tex_density->eval_1(si, active), n);
            if (m_tex_roughness)
                tex[4] = lanes(m_tex_roughness->eval_1(si, active), n);
            dr::eval(tex[0], tex[1], tex[2], tex[3], tex[4]);
            for (int k = 0; k < 5; ++k)
                if (dr::width(tex[k]) == n && (k >= 3 ? (k == 3 ? (bool) m_tex_density : (bool) m_tex_roughness)
                                                      : (bool) m_tex_color))
                    ptr[k] = tex[k].data();
        } else {
            DRJIT_MARK_USED(si);
            DRJIT_MARK_USED(active);
            DRJIT_MARK_USED(n);
            DRJIT_MARK_USED(tex);
            DRJIT_MARK_USED(ptr);
        }
    }

    /// lacquer_detail::check for the per-element calls, plus one warning per material when
    /// elements had invalid texture values (out of range or NaN: the core returns zero for
    /// them, so those pixels render black), with the core's message naming the first.
    void check_varying(lq_status status, const char *what) const {
        if (status == LQ_ERR_INVALID_ELEMENT && !m_warned.exchange(true))
            Log(Warn, "lacquer: %s: %s. Those elements evaluate to zero (black); this warning is "
                      "shown once per material.", what, lq_last_error());
        lacquer_detail::check(status, what);
    }

    // ---- JIT variants: the batched path -------------------------------------------------

    /// True when Dr.Jit is tracing this call symbolically (a symbolic loop or virtual call:
    /// Mitsuba's default in llvm variants). The library cannot run on symbolic arrays, so the
    /// callers return zero (eval, pdf) or an invalid sample there. A symbolic virtual call
    /// traces every live BSDF of the variant (Dr.Jit's registry holds no notion of which
    /// scene an object belongs to), so an object not used by the scene being rendered gets
    /// here too: its zero is never selected and that render is unchanged. One warning per
    /// object names the fix for scenes that do use it.
    bool symbolic_scope() const {
        if (!jit_flag(JitFlag::SymbolicScope))
            return false;
        if (!m_warned_symbolic.exchange(true))
            Log(Warn, "lacquer: the lacquer BSDF \"%s\" (model %s) is being traced inside a symbolic "
                      "Dr.Jit loop or call (Mitsuba's default in llvm variants), where it evaluates to "
                      "zero (black) and its samples are invalid. Harmless if the scene being rendered "
                      "does not use it (a symbolic call traces every live BSDF). To render a scene that "
                      "uses it, use wavefront mode: lacquer_mitsuba.render(scene, ...), or "
                      "`with lacquer_mitsuba.wavefront(): mi.render(scene)`, i.e. "
                      "dr.set_flag(dr.JitFlag.SymbolicLoops, False) and "
                      "dr.set_flag(dr.JitFlag.SymbolicCalls, False) (docs/mitsuba.md). Shown once "
                      "per object.", this->id().empty() ? std::string("(no id)") : std::string(this->id()), m_model);
        return true;
    }

    /// Width of a batch: the widest operand (width-1 operands are broadcast).
    template <typename... Ts>
    static size_t batch_width(const Ts &...values) {
        size_t n = 1;
        ((n = std::max(n, (size_t) dr::width(values))), ...);
        return n;
    }

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

    // ---- llvm_ad_spectral: the batched path at each lane's four wavelengths -------------
    // Materials with spectral physics (LQ_LOBE_SPECTRAL) go through lq_eval_spectral /
    // lq_sample_spectral with the active lanes packed on the host (4 wavelengths per lane),
    // the pdf through lq_pdf_soa (it does not depend on λ), as scalar_spectral does with
    // lq_pdf_one. Every other material takes the RGB batched path and its result is upsampled
    // per lane with Mitsuba's sRGB model, exactly as from_rgb does in scalar_spectral, so the
    // two spectral variants agree.

    /// RGB lanes (evaluated host arrays of width n) as this variant's spectrum: the arrays
    /// themselves in the RGB variants, Mitsuba's upsampling at si.wavelengths in the spectral.
    UnpolarizedSpectrum rgb_lanes(FloatJ &r, FloatJ &g, FloatJ &b, const SurfaceInteraction3f &si) const {
        if constexpr (is_spectral_v<Spectrum>)
            return upsample_lanes(r.data(), g.data(), b.data(), 1, dr::width(r), si);
        else {
            DRJIT_MARK_USED(si);
            return UnpolarizedSpectrum(Float(r), Float(g), Float(b));
        }
    }

    /// Interleaved RGB (3n floats) as this variant's spectrum (see rgb_lanes).
    UnpolarizedSpectrum rgb_interleaved(const std::vector<float> &rgb, size_t n,
                                        const SurfaceInteraction3f &si) const {
        if constexpr (is_spectral_v<Spectrum>)
            return upsample_lanes(rgb.data(), rgb.data() + 1, rgb.data() + 2, 3, n, si);
        else {
            DRJIT_MARK_USED(si);
            Vector3f v = deinterleave3(rgb, n);
            return UnpolarizedSpectrum(v.x(), v.y(), v.z());
        }
    }

    /// from_rgb per lane (JIT spectral variants): Mitsuba's sRGB model coefficients fetched on
    /// the host for each lane's RGB scaled to max 1 (srgb_model_fetch is scalar only), then
    /// evaluated at the lane's wavelengths and scaled back.
    UnpolarizedSpectrum upsample_lanes(const float *r, const float *g, const float *b, size_t stride,
                                       size_t n, const SurfaceInteraction3f &si) const {
        if constexpr (dr::is_jit_v<Float> && is_spectral_v<Spectrum>) {
            std::vector<float> c0(n), c1(n), c2(n), sc(n);
            // Mitsuba loads its coefficient table on the first fetch: do that here, on the
            // calling thread (a failure then raises here, not inside a pool worker).
            (void) srgb_model_fetch(Color<float, 3>(0.5f, 0.5f, 0.5f));
            // On Dr.Jit's pool in blocks of 4096 lanes (about 60 ns per lane on one core).
            spectral_chunks(n, "srgb_model_fetch", [&](size_t begin, size_t end) {
                for (size_t i = begin; i < end; ++i) {
                    float x = r[i * stride], y = g[i * stride], z = b[i * stride];
                    float scale = std::max({ x, y, z });
                    if (!(scale > 0.f)) {
                        c0[i] = c1[i] = c2[i] = sc[i] = 0.f;
                        continue;
                    }
                    dr::Array<float, 3> co = srgb_model_fetch(Color<float, 3>(x / scale, y / scale, z / scale));
                    c0[i] = co.x();
                    c1[i] = co.y();
                    c2[i] = co.z();
                    sc[i] = scale;
                }
                return LQ_OK;
            }, 4096);
            dr::Array<Float, 3> coeff(dr::load<Float>(c0.data(), n), dr::load<Float>(c1.data(), n),
                                      dr::load<Float>(c2.data(), n));
            return dr::load<Float>(sc.data(), n) * srgb_model_eval<UnpolarizedSpectrum>(coeff, si.wavelengths);
        } else {
            DRJIT_MARK_USED(r); DRJIT_MARK_USED(g); DRJIT_MARK_USED(b);
            DRJIT_MARK_USED(stride); DRJIT_MARK_USED(n); DRJIT_MARK_USED(si);
            return UnpolarizedSpectrum(0.f);
        }
    }

    /// Runs `call(begin, end)` (a C ABI call on elements [begin, end)) over k elements in
    /// blocks of `block` on Dr.Jit's thread pool (nanothread's default pool, whose workers also
    /// run the LLVM kernels: a pool of our own would compete with them for the cores). The
    /// spectral calls run on the calling thread, and a handle may be used from many threads at
    /// once. Throws the first failure that is not a per-element status, with its message
    /// (lq_last_error is per thread).
    template <typename Call>
    static void spectral_chunks(size_t k, const char *what, Call call, size_t block = 512) {
        if (k == 0)
            return;
        size_t blocks = (k + block - 1) / block;
        std::vector<lq_status> status(blocks, LQ_OK);
        std::vector<std::string> message(blocks);
        drjit::parallel_for(drjit::blocked_range<size_t>(0, k, block), [&](drjit::blocked_range<size_t> r) {
            size_t b = *r.begin() / block;
            status[b] = call(*r.begin(), *r.end());
            if (status[b] != LQ_OK)
                message[b] = lq_last_error();
        });
        for (size_t b = 0; b < blocks; ++b)
            if (status[b] != LQ_OK && status[b] != LQ_ERR_INVALID_DIRECTION && status[b] != LQ_ERR_INVALID_ELEMENT)
                Throw("lacquer: %s failed (%s): %s", what, lq_status_name(status[b]), message[b]);
    }

    /// The inputs of one spectral batch call: the active lanes' wavelengths (4 per lane), uv and
    /// footprint (when spatial), packed on the host in lane order; `lane[j]` is the lane of
    /// packed element j.
    struct SpectralPack {
        std::vector<uint32_t> lane;
        std::vector<float> lambda, uv, duv;
    };

    /// Evaluates the wavelengths, the mask and (spatial) uv / footprint of n lanes and packs
    /// those of the active lanes.
    void pack_spectral(const SurfaceInteraction3f &si, const Mask &active, size_t n, bool spatial,
                        Float &uv_b, Float &duv_b, SpectralPack &p) const {
        if constexpr (dr::is_jit_v<Float> && is_spectral_v<Spectrum>) {
            FloatJ l[4];
            for (size_t c = 0; c < 4; ++c)
                l[c] = lanes(si.wavelengths[c], n);
            MaskJ act = lanes(active, n);
            dr::eval(l[0], l[1], l[2], l[3], act);
            const float *pl[4] = { l[0].data(), l[1].data(), l[2].data(), l[3].data() };
            const float *uv = spatial ? host(uv_b) : nullptr, *duv = spatial ? host(duv_b) : nullptr;
            const uint8_t *pm = mask_bytes(act);
            dr::sync_thread();
            p.lane.reserve(n);
            for (size_t i = 0; i < n; ++i)
                if (pm[i])
                    p.lane.push_back((uint32_t) i);
            size_t k = p.lane.size();
            p.lambda.resize(4 * k);
            if (spatial) {
                p.uv.resize(2 * k);
                p.duv.resize(4 * k);
            }
            for (size_t j = 0; j < k; ++j) {
                size_t i = p.lane[j];
                for (size_t c = 0; c < 4; ++c)
                    p.lambda[4 * j + c] = pl[c][i];
                if (spatial) {
                    std::memcpy(&p.uv[2 * j], uv + 2 * i, 2 * sizeof(float));
                    std::memcpy(&p.duv[4 * j], duv + 4 * i, 4 * sizeof(float));
                }
            }
        } else {
            DRJIT_MARK_USED(si); DRJIT_MARK_USED(active); DRJIT_MARK_USED(n);
            DRJIT_MARK_USED(spatial); DRJIT_MARK_USED(uv_b); DRJIT_MARK_USED(duv_b); DRJIT_MARK_USED(p);
        }
    }

    /// The packed elements' 3-vectors of (x, y, z) lanes, interleaved.
    static std::vector<float> pack3(const SpectralPack &p, const Vector3f &v, size_t n) {
        FloatJ x = lanes(v.x(), n), y = lanes(v.y(), n), z = lanes(v.z(), n);
        dr::eval(x, y, z);
        const float *px = x.data(), *py = y.data(), *pz = z.data();
        dr::sync_thread();
        std::vector<float> out(3 * p.lane.size());
        for (size_t j = 0; j < p.lane.size(); ++j) {
            size_t i = p.lane[j];
            out[3 * j] = px[i];
            out[3 * j + 1] = py[i];
            out[3 * j + 2] = pz[i];
        }
        return out;
    }

    /// Four packed values per element back to four lane arrays of width n (0 elsewhere).
    static UnpolarizedSpectrum unpack4(const SpectralPack &p, const std::vector<float> &v, size_t n) {
        if constexpr (dr::is_jit_v<Float> && is_spectral_v<Spectrum>) {
            std::vector<float> out(4 * n, 0.f);
            for (size_t j = 0; j < p.lane.size(); ++j)
                for (size_t c = 0; c < 4; ++c)
                    out[c * n + p.lane[j]] = v[4 * j + c];
            return UnpolarizedSpectrum(dr::load<Float>(out.data(), n), dr::load<Float>(out.data() + n, n),
                                       dr::load<Float>(out.data() + 2 * n, n),
                                       dr::load<Float>(out.data() + 3 * n, n));
        } else {
            DRJIT_MARK_USED(p); DRJIT_MARK_USED(v); DRJIT_MARK_USED(n);
            return UnpolarizedSpectrum(0.f);
        }
    }

    /// eval_pdf_impl of llvm_ad_spectral for LQ_LOBE_SPECTRAL materials.
    std::pair<Spectrum, Float> eval_pdf_spectral_lanes(const SurfaceInteraction3f &si, const Vector3f &wo,
                                                       Mask active, size_t n, bool spatial, Float &uv_b,
                                                       Float &duv_b, bool want_f, bool want_pdf) const {
        lq_material *m = m_material.get();
        Float pdf_v(0.f);
        if (want_pdf) {
            FloatJ ax = lanes(wo.x(), n), ay = lanes(wo.y(), n), az = lanes(wo.z(), n),
                   bx = lanes(si.wi.x(), n), by = lanes(si.wi.y(), n), bz = lanes(si.wi.z(), n);
            MaskJ act = lanes(active, n);
            FloatJ pdf_j = outputs<FloatJ>(n);
            dr::eval(ax, ay, az, bx, by, bz, act);
            const float *pax = ax.data(), *pay = ay.data(), *paz = az.data(), *pbx = bx.data(),
                        *pby = by.data(), *pbz = bz.data();
            const uint8_t *pa = mask_bytes(act);
            float *pp = pdf_j.data();
            dr::sync_thread();
            lacquer_detail::check(lq_pdf_soa(m, n, pax, pay, paz, pbx, pby, pbz, pa, pp), "lq_pdf_soa");
            pdf_v = dr::select(active, Float(pdf_j), 0.f);
        }
        Spectrum value(0.f);
        if (want_f) {
            SpectralPack p;
            pack_spectral(si, active, n, spatial, uv_b, duv_b, p);
            std::vector<float> a = pack3(p, wo, n), b = pack3(p, si.wi, n), f(4 * p.lane.size());
            spectral_chunks(p.lane.size(), "lq_eval_spectral", [&](size_t s, size_t e) {
                return lq_eval_spectral(m, e - s, &a[3 * s], &b[3 * s], spatial ? &p.uv[2 * s] : nullptr,
                                        spatial ? &p.duv[4 * s] : nullptr, &p.lambda[4 * s], &f[4 * s]);
            });
            UnpolarizedSpectrum v = unpack4(p, f, n) * dr::maximum(wo.z(), 0.f);
            if (m_tint)
                v *= m_tint->eval(si, active);
            value = depolarizer<Spectrum>(v) & active;
        }
        return { value, pdf_v };
    }

    /// sample() of llvm_ad_spectral for LQ_LOBE_SPECTRAL materials.
    std::pair<BSDFSample3f, Spectrum> sample_spectral_lanes(const SurfaceInteraction3f &si, Float sample1,
                                                            const Point2f &sample2, bool smooth_on,
                                                            bool delta_on, Mask active, size_t n,
                                                            bool spatial, Float &uv_b, Float &duv_b) const {
        SpectralPack p;
        pack_spectral(si, active, n, spatial, uv_b, duv_b, p);
        size_t k = p.lane.size();
        std::vector<float> wo = pack3(p, si.wi, n), u = pack3(p, Vector3f(sample1, sample2.x(), sample2.y()), n),
                           wi(3 * k), weight(4 * k), pdf(k);
        std::vector<uint32_t> flags(k);
        spectral_chunks(k, "lq_sample_spectral", [&](size_t s, size_t e) {
            return lq_sample_spectral(m_material.get(), e - s, &wo[3 * s], &u[3 * s],
                                      spatial ? &p.uv[2 * s] : nullptr, spatial ? &p.duv[4 * s] : nullptr,
                                      &p.lambda[4 * s], &wi[3 * s], &weight[4 * s], &pdf[s], &flags[s]);
        });
        // Back to lanes: inactive lanes are failed samples.
        std::vector<float> wi_n(3 * n, 0.f), pdf_n(n, 0.f);
        std::vector<uint32_t> fl_n(n, LQ_SAMPLE_FAILED);
        for (size_t j = 0; j < k; ++j) {
            size_t i = p.lane[j];
            for (size_t c = 0; c < 3; ++c)
                wi_n[c * n + i] = wi[3 * j + c];
            pdf_n[i] = pdf[j];
            fl_n[i] = flags[j];
        }
        Vector3f wi_v(dr::load<Float>(wi_n.data(), n), dr::load<Float>(wi_n.data() + n, n),
                      dr::load<Float>(wi_n.data() + 2 * n, n));
        Float pdf_v = dr::load<Float>(pdf_n.data(), n);
        UInt32 fl = dr::load<UInt32>(fl_n.data(), n);
        Mask delta = (fl & UInt32(LQ_SAMPLE_DELTA)) != 0u;
        Mask ok = active && (fl & UInt32(LQ_SAMPLE_FAILED)) == 0u && pdf_v > 0.f;
        if (!delta_on)
            ok &= !delta;
        if (!smooth_on)
            ok &= delta;
        BSDFSample3f bs = dr::zeros<BSDFSample3f>();
        bs.wo = dr::select(ok, wi_v, 0.f);
        bs.pdf = dr::select(ok, pdf_v, 0.f);
        bs.eta = 1.f;
        bs.sampled_type = dr::select(delta, UInt32(+BSDFFlags::DeltaReflection), UInt32(m_smooth_sampled));
        bs.sampled_component = dr::select(delta, UInt32(m_delta_component), UInt32(0u));
        UnpolarizedSpectrum value = unpack4(p, weight, n);
        if (m_tint)
            value *= m_tint->eval(si, active);
        return { bs, depolarizer<Spectrum>(value) & ok };
    }

    /// uv and footprints of a batch. Lanes without ray differentials (zero partials, e.g.
    /// secondary bounces) get an effectively infinite footprint: the contract's mean lobe,
    /// as the scalar path gives them by calling the functions without uv.
    bool batch_spatial(const SurfaceInteraction3f &si, size_t n, Float &uv, Float &duv) const {
        if (!m_spatial || !si.has_uv_partials())
            return false;
        Mask has = dr::any(si.duv_dx != 0.f) || dr::any(si.duv_dy != 0.f);
        // Decided on the host: dr::none_or<false> is always false for JIT arrays (it never
        // evaluates), which sent every batch of a sparkle material with partials arrays (all
        // zero, e.g. Mitsuba's `path`) through the interleaved spatial calls with the huge
        // footprint, about twice the cost of the mean lobe's SoA calls.
        MaskJ has_j = lanes(has, n);
        dr::eval(has_j);
        const uint8_t *hp = mask_bytes(has_j);
        dr::sync_thread();
        if (std::none_of(hp, hp + n, [](uint8_t b) { return b != 0; }))
            return false;
        const float huge = 1e6f;
        uv = interleave(n, { si.uv.x(), si.uv.y() });
        duv = interleave(n, { dr::select(has, si.duv_dx.x(), huge), dr::select(has, si.duv_dx.y(), 0.f),
                              dr::select(has, si.duv_dy.x(), 0.f), dr::select(has, si.duv_dy.y(), huge) });
        return true;
    }

    /// "Every lobe": the plain C calls (a lobe mask never holds these bits).
    static constexpr uint32_t kAllLobes = 0xffffffffu;

    /// Split materials: the lobe mask (LQ_LOBE_DIFFUSE / _GLOSSY / _COAT) of the components
    /// the context enables, as Mitsuba's own multi-lobe BSDFs ask (`ctx.is_enabled(kind, i)`
    /// per component).
    uint32_t context_lobes(const BSDFContext &ctx) const {
        uint32_t mask = 0;
        for (size_t i = 0; i < m_part_select.size(); ++i) {
            uint32_t kinds = m_components[i] & (+BSDFFlags::DiffuseReflection | +BSDFFlags::GlossyReflection |
                                                +BSDFFlags::DeltaReflection);
            if (ctx.is_enabled((BSDFFlags) kinds, (uint32_t) i))
                mask |= m_part_select[i];
        }
        return mask;
    }

    /// The lobe argument of eval / pdf / eval_pdf: 0 = nothing enabled, kAllLobes = the plain
    /// calls (every component of a split material, or the smooth component of another one).
    uint32_t eval_lobes(const BSDFContext &ctx) const {
        if (!m_split)
            return smooth_enabled(ctx) ? kAllLobes : 0u;
        uint32_t lobes = context_lobes(ctx);
        return lobes == m_all_lobes ? kAllLobes : lobes;
    }

    /// Split materials: the sampled type and component of a non-delta sample when the
    /// groups `lobes` are enabled: exact when one non-delta component is enabled; with
    /// several, the core does not report which one it chose: the union of their types and
    /// the first of them.
    void nondelta_component(uint32_t lobes, uint32_t &type, uint32_t &comp) const {
        type = 0;
        comp = 0;
        bool first = true;
        for (size_t i = 0; i < m_part_select.size(); ++i) {
            if (!(lobes & m_part_select[i]) || (m_components[i] & +BSDFFlags::DeltaReflection))
                continue;
            type |= m_components[i] & (+BSDFFlags::DiffuseReflection | +BSDFFlags::GlossyReflection);
            if (first)
                comp = (uint32_t) i;
            first = false;
        }
    }

    /// True when the context enables the smooth component (component 0) through any of its
    /// lobe kinds: a context asking for glossy reflection gets the diffuse + glossy component
    /// (the C ABI evaluates the smooth lobes together).
    bool smooth_enabled(const BSDFContext &ctx) const {
        if (!m_has_smooth)
            return false;
        for (uint32_t bit : { +BSDFFlags::DiffuseReflection, +BSDFFlags::GlossyReflection })
            if ((m_smooth_sampled & bit) && ctx.is_enabled((BSDFFlags) bit, 0))
                return true;
        return false;
    }

    /// Index of the parameter called `key`, or a Mitsuba error listing the model's parameters.
    size_t find_param(const std::string &key) const {
        for (size_t i = 0; i < m_params.size(); ++i)
            if (m_params[i].name == key)
                return i;
        std::string names;
        for (const auto &p : m_params)
            names += (names.empty() ? "" : ", ") + p.name;
        Throw("lacquer: unknown property \"%s\": model \"%s\" has the parameters %s (see `lacquer "
              "models`), besides model, preset, material, tint and footprint", key, m_model, names);
    }

    /// A typed Mitsuba property as the parameter's JSON value, checked against its kind and
    /// range (the core checks again when the material is built).
    static std::string property_value(const Properties &props, const lacquer_detail::ParamInfo &p,
                                      const std::string &key, Properties::Type type) {
        using namespace lacquer_detail;
        using T = Properties::Type;
        auto wrong = [&]() -> std::string {
            Throw("lacquer: property \"%s\" has the wrong type: give %s (%s; %s)", key, p.xml_tag(),
                  p.range(), p.doc);
        };
        auto in_range = [&](double v) {
            if (!(v >= p.min && v <= p.max))
                Throw("lacquer: property \"%s\" = %g is out of range: it takes %s (%s)", key, v,
                      p.range(), p.doc);
            return json_number(v);
        };
        switch (p.kind) {
            case LQ_PARAM_SCALAR:
            case LQ_PARAM_INTEGER:
                if (type != T::Float && type != T::Integer)
                    return wrong();
                return in_range(props.get<double>(key));
            case LQ_PARAM_COLOR: {
                if (type == T::Float || type == T::Integer)
                    return in_range(props.get<double>(key));
                if (type == T::Color || type == T::Vector) {
                    Color<double, 3> c = props.get<Color<double, 3>>(key);
                    return "[" + in_range(c.x()) + "," + in_range(c.y()) + "," + in_range(c.z()) + "]";
                }
                return wrong();
            }
            case LQ_PARAM_BOOL:
                if (type != T::Bool)
                    return wrong();
                return props.get<bool>(key) ? "true" : "false";
            case LQ_PARAM_CHOICE: {
                if (type != T::String)
                    return wrong();
                std::string v = props.get<std::string>(key);
                std::string all = "|" + p.choices + "|";
                if (all.find("|" + v + "|") == std::string::npos)
                    Throw("lacquer: property \"%s\" = \"%s\" is not valid: it takes %s (%s)", key, v,
                          p.range(), p.doc);
                return json_string(v);
            }
            case LQ_PARAM_JSON:
                if (type != T::String)
                    return wrong();
                return props.get<std::string>(key);
            default:
                if (type != T::String)
                    return wrong();
                return json_string(props.get<std::string>(key));
        }
    }

    /// A texture object given for parameter i. A constant texture (`uniform`, `rgb`) becomes
    /// the plain value and returns true; any other texture on
    /// base_color, flake_density or coat_roughness of coated_paint is kept, evaluated per lane,
    /// and returns true; on another parameter or model it raises a Mitsuba error.
    bool set_texture(const Properties &props, const std::string &key, size_t i) {
        using namespace lacquer_detail;
        const ParamInfo &p = m_params[i];
        if (!p.numeric() && !p.color())
            return false; // property_value names the expected type
        ref<Texture> t = p.color() ? props.get_texture<Texture>(key)
                                   : props.get_unbounded_texture<Texture>(key);
        // Constant: Mitsuba's uniform and rgb textures (is_spatially_varying() is no guide:
        // a mesh_attribute reports false).
        std::string_view cls = t->class_name();
        if (cls == "UniformSpectrum" || cls == "SRGBReflectanceSpectrum") {
            // Texture values are float32: the shortest decimal that round-trips, so that a
            // constant texture of 0.2 is the material of the plain property 0.2.
            if (p.numeric()) {
                m_values[i] = json_float(scalar_of(t->mean()));
                return true;
            }
            if constexpr (is_rgb_v<Spectrum>) {
                auto c = t->eval(dr::zeros<SurfaceInteraction3f>());
                m_values[i] = "[" + json_float(scalar_of(c.x())) + "," + json_float(scalar_of(c.y())) +
                              "," + json_float(scalar_of(c.z())) + "]";
                return true;
            }
            Throw("lacquer: property \"%s\" is a constant texture object: in this variant give the "
                  "colour as %s (%s)", key, p.xml_tag(), p.range());
        }
        bool supported = m_model == "coated_paint" &&
                         (key == "base_color" || key == "flake_density" || key == "coat_roughness");
        if (!supported)
            Throw("lacquer: property \"%s\" is a texture, but model \"%s\" takes textures only on "
                  "coated_paint's base_color, flake_density and coat_roughness; give %s (%s), or "
                  "use \"tint\" (a texture multiplying f_r)", key, m_model, p.xml_tag(), p.range());
        (key == "base_color" ? m_tex_color : key == "flake_density" ? m_tex_density : m_tex_roughness) = t;
        return true;
    }

    /// Builds the material from parameter values (JSON text per parameter); on success it
    /// replaces the current one, on failure `error` says why and nothing changes.
    bool rebuild(const std::vector<std::string> &values, std::string &error) {
        std::string json = "{\"model\": " + lacquer_detail::json_string(m_model);
        for (size_t i = 0; i < m_params.size(); ++i)
            json += ", " + lacquer_detail::json_string(m_params[i].name) + ": " + values[i];
        json += "}";
        lq_material *raw = nullptr;
        lq_status s = lq_material_from_json(json.c_str(), &raw);
        if (s != LQ_OK) {
            error = std::string(lq_status_name(s)) + ": " + lq_last_error();
            return false;
        }
        m_material = lacquer_detail::MaterialPtr(raw, lacquer_detail::MaterialDeleter());
        char *canonical = nullptr;
        lacquer_detail::check(lq_material_to_json(raw, &canonical), "lq_material_to_json");
        m_json = canonical;
        lq_string_free(canonical);
        return true;
    }

    /// The traversable values from the current parameter values.
    void store_slots() {
        for (size_t i = 0; i < m_params.size(); ++i) {
            std::vector<double> v = lacquer_detail::json_numbers(m_values[i]);
            if (m_params[i].numeric() && v.size() == 1) {
                m_scalar[i] = Float((float) v[0]);
            } else if (m_params[i].color()) {
                if (v.size() == 1)
                    v = { v[0], v[0], v[0] };
                if (v.size() == 3)
                    m_color[i] = Color3f((float) v[0], (float) v[1], (float) v[2]);
            }
        }
    }

    template <typename T> static double scalar_of(const T &v) {
        if constexpr (dr::is_jit_v<T>)
            return dr::width(v) == 0 ? std::nan("") : (double) dr::slice(v, 0);
        else
            return (double) v;
    }

    /// Mitsuba's flags and components from the core's lobe report (lq_material_lobes) and
    /// the diffuse albedo (lq_material_diffuse_reflectance).
    void update_flags() {
        uint32_t lobes = 0;
        lacquer_detail::check(lq_material_lobes(m_material.get(), &lobes), "lq_material_lobes");
        lacquer_detail::check(lq_material_diffuse_reflectance(m_material.get(), m_diffuse),
                              "lq_material_diffuse_reflectance");
        if constexpr (is_spectral_v<Spectrum>)
            if (textured() && (lobes & LQ_LOBE_SPECTRAL))
                Throw("lacquer: textured parameters of a material with spectral physics (thin-film "
                      "pearl flakes: pearl_density > 0) cannot render in a spectral variant: the C ABI "
                      "has no per-element spectral call. Render it in scalar_rgb or llvm_ad_rgb, or "
                      "drop the texture or the pearl flakes");
        if (textured()) {
            // One element through the per-element call: a material the core cannot vary
            // (e.g. pigment_model "eon") fails here, at load, with the core's reason.
            float z0 = 0.f, z1 = 1.f, c = 0.5f, d = 0.f, a = 0.1f, f[3], pdf;
            lq_status s = lq_eval_pdf_varying(
                m_material.get(), 1, &z0, &z0, &z1, &z0, &z0, &z1, m_tex_color ? &c : nullptr,
                m_tex_color ? &c : nullptr, m_tex_color ? &c : nullptr, m_tex_density ? &d : nullptr,
                m_tex_roughness ? &a : nullptr, nullptr, &f[0], &f[1], &f[2], &pdf);
            if (s != LQ_OK)
                Throw("lacquer: this material cannot take textured parameters (%s): %s",
                      lq_status_name(s), lq_last_error());
        }
        // A textured base_color has a diffuse lobe wherever the texture is not black.
        if (m_tex_color)
            lobes |= LQ_LOBE_DIFFUSE;
        m_lobes = lobes;
        // The per-element calls evaluate the mean lobe: a textured paint has no sparkle.
        m_spatial = m_footprint && (lobes & LQ_LOBE_SPATIALLY_VARYING) && !textured();
        uint32_t smooth = 0;
        if (lobes & LQ_LOBE_DIFFUSE)
            smooth |= +BSDFFlags::DiffuseReflection;
        if (lobes & LQ_LOBE_GLOSSY)
            smooth |= +BSDFFlags::GlossyReflection;
        m_smooth_sampled = smooth;
        if (smooth && (lobes & LQ_LOBE_ANISOTROPIC))
            smooth |= +BSDFFlags::Anisotropic;
        m_smooth_type = smooth;
        m_has_smooth = smooth != 0;
        m_has_delta = (lobes & LQ_LOBE_DELTA) != 0;
        m_components.clear();
        if (m_has_smooth)
            m_components.push_back(smooth | BSDFFlags::FrontSide);
        m_delta_component = (uint32_t) m_components.size();
        if (m_has_delta)
            m_components.push_back(BSDFFlags::DeltaReflection | BSDFFlags::FrontSide);
        // One component per lobe group of the core (coated_paint: pigment, glossy base lobes,
        // coat) when the lobe calls can evaluate them: not for textured paints (the
        // per-element calls have no lobe mask) nor for spectral physics in spectral variants.
        size_t parts = 0;
        lacquer_detail::check(lq_material_lobe_part_count(m_material.get(), &parts), "lq_material_lobe_part_count");
        bool split = parts > 1 && !textured();
        if constexpr (is_spectral_v<Spectrum>)
            if (lobes & LQ_LOBE_SPECTRAL)
                split = false;
        m_split = split;
        m_part_select.clear();
        m_all_lobes = 0;
        if (split) {
            m_components.clear();
            for (size_t i = 0; i < parts; ++i) {
                uint32_t select = 0, kinds = 0;
                lacquer_detail::check(lq_material_lobe_part(m_material.get(), i, &select, &kinds),
                                      "lq_material_lobe_part");
                uint32_t flags = +BSDFFlags::FrontSide;
                if (kinds & LQ_LOBE_DIFFUSE)
                    flags |= +BSDFFlags::DiffuseReflection;
                if (kinds & LQ_LOBE_GLOSSY)
                    flags |= +BSDFFlags::GlossyReflection;
                if (kinds & LQ_LOBE_DELTA) {
                    flags |= +BSDFFlags::DeltaReflection;
                    m_delta_component = (uint32_t) i;
                }
                if ((kinds & (LQ_LOBE_DIFFUSE | LQ_LOBE_GLOSSY)) && (lobes & LQ_LOBE_ANISOTROPIC))
                    flags |= +BSDFFlags::Anisotropic;
                m_components.push_back(flags);
                m_part_select.push_back(select);
                m_all_lobes |= select;
            }
        }
        m_flags = 0;
        for (uint32_t c : m_components)
            m_flags |= c;
        if (lobes & LQ_LOBE_NON_RECIPROCAL)
            m_flags |= +BSDFFlags::NonSymmetric;
        if ((lobes & LQ_LOBE_SPATIALLY_VARYING) || (m_tint && m_tint->is_spatially_varying()) || textured())
            m_flags |= +BSDFFlags::SpatiallyVarying;
        if (m_spatial)
            m_flags |= +BSDFFlags::NeedsDifferentials;
    }

    lacquer_detail::MaterialPtr m_material;
    std::string m_json, m_model;
    std::vector<lacquer_detail::ParamInfo> m_params;
    /// JSON text of each parameter of the material in use.
    std::vector<std::string> m_values;
    /// Traversable copies (scalar / colour parameters; the other entries are unused). Never
    /// resized after construction: mi.traverse holds pointers to them.
    std::vector<Float> m_scalar;
    std::vector<Color3f> m_color;
    ref<Texture> m_tint;
    /// Textures of base_color, flake_density and coat_roughness (null: the material's value).
    ref<Texture> m_tex_color, m_tex_density, m_tex_roughness;
    /// Set once an invalid per-element value was reported (one warning per material).
    mutable std::atomic<bool> m_warned{ false };
    /// symbolic_scope() has warned (once per object).
    mutable std::atomic<bool> m_warned_symbolic{ false };
    float m_diffuse[3] = { 0.f, 0.f, 0.f };
    bool m_footprint = true, m_spatial = false, m_has_smooth = true, m_has_delta = false;
    uint32_t m_smooth_type = 0, m_smooth_sampled = 0, m_delta_component = 1, m_lobes = 0;
    /// Components = the core's lobe groups (lq_material_lobe_part): their lobe-mask bits, and
    /// the union of them (the plain calls).
    bool m_split = false;
    std::vector<uint32_t> m_part_select;
    uint32_t m_all_lobes = 0;

    MI_TRAVERSE_CB(Base, m_tint, m_tex_color, m_tex_density, m_tex_roughness)
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
    fn(name, "llvm_ad_spectral", ObjectType::BSDF, [](void *, const Properties &p) -> ref<Object> {
        return new LacquerBSDF<FloatL, Spectrum<FloatL, 4>>(p);
    });
#endif
}
