// lacquer.hpp: a thin, header-only C++17 wrapper over the C ABI in lacquer.h.
// SPDX-License-Identifier: MIT OR Apache-2.0
//
// RAII for material handles and library strings, exceptions (lacquer::Error) for statuses,
// and length-checked std::vector overloads. No logic of its own beyond that: every number
// comes from the C functions. Conventions (frame, units, threads) are those of lacquer.h.
//
//   lacquer::Material m = lacquer::Material::preset("white_lambert");
//   std::array<float, 3> f = m.eval({0, 0, 1}, {0, 0.6f, 0.8f});
//
// Per-element errors (LQ_ERR_INVALID_DIRECTION, LQ_ERR_INVALID_ELEMENT) are thrown as
// lacquer::Error too, AFTER the output arrays were completely written (invalid elements as 0),
// so a caller that catches them can still use the outputs.
#ifndef LACQUER_HPP
#define LACQUER_HPP

#include "lacquer.h"

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace lacquer {

/// A failed call: the status and the library's message (lq_last_error()).
class Error : public std::runtime_error {
public:
    Error(lq_status status, const std::string &message)
        : std::runtime_error(std::string(lq_status_name(status)) + ": " + message),
          status_(status) {}
    /// The LQ_ERR_* code.
    lq_status status() const noexcept { return status_; }
    /// True for the per-element statuses, whose outputs were fully written.
    bool outputs_written() const noexcept {
        return status_ == LQ_ERR_INVALID_DIRECTION || status_ == LQ_ERR_INVALID_ELEMENT;
    }

private:
    lq_status status_;
};

namespace detail {

inline void check(lq_status s) {
    if (s != LQ_OK) {
        throw Error(s, lq_last_error());
    }
}

/// Copies and frees a string the library allocated.
inline std::string take(char *p) {
    std::unique_ptr<char, void (*)(char *)> owned(p, lq_string_free);
    return owned ? std::string(owned.get()) : std::string();
}

inline void check_sizes(std::size_t n3, std::size_t other, const char *what) {
    if (n3 % 3 != 0 || other != n3) {
        throw Error(LQ_ERR_INVALID_ARGUMENT,
                    std::string("array sizes do not match (") + what +
                        "): direction arrays need 3 values per element and equal lengths");
    }
}

}  // namespace detail

/// The library's ABI version, (major << 16) | minor.
inline std::uint32_t abi_version() noexcept { return lq_abi_version(); }

/// The library's release version, e.g. "0.1.0".
inline std::string version() { return lq_version(); }

/// Throws unless the loaded library is compatible with the header this was compiled with.
inline void check_abi() {
    const std::uint32_t lib = lq_abi_version();
    if ((lib >> 16) != LQ_ABI_VERSION_MAJOR || (lib & 0xffffu) < LQ_ABI_VERSION_MINOR) {
        throw Error(LQ_ERR_INVALID_ARGUMENT,
                    "liblacquer ABI " + std::to_string(lib >> 16) + "." +
                        std::to_string(lib & 0xffffu) + " is incompatible with lacquer.h ABI " +
                        std::to_string(LQ_ABI_VERSION_MAJOR) + "." +
                        std::to_string(LQ_ABI_VERSION_MINOR));
    }
}

/// Every registered model (JSON array; see lq_models_json).
inline std::string models_json() {
    char *s = nullptr;
    detail::check(lq_models_json(&s));
    return detail::take(s);
}

/// Every preset (JSON array; see lq_presets_json).
inline std::string presets_json() {
    char *s = nullptr;
    detail::check(lq_presets_json(&s));
    return detail::take(s);
}

/// One importance sample.
struct Sample {
    std::array<float, 3> wi{};      ///< sampled direction toward the light
    std::array<float, 3> weight{};  ///< f cos(theta_i) / pdf
    float pdf = 0.0f;               ///< solid-angle density (0: failed sample)
    std::uint32_t flags = 0;        ///< LQ_SAMPLE_* bits
};

/// Outcome of the shipped checks.
struct CheckResult {
    bool passed = false;      ///< every claimed property held
    std::string report_json;  ///< the full report (verdicts, figures)
};

/// An immutable material; cheap to move, not copyable, safe to share across threads by
/// const reference.
class Material {
public:
    /// Parses material JSON ({"model": ...} or {"preset": ...}); throws lacquer::Error.
    static Material from_json(const std::string &json) {
        lq_material *m = nullptr;
        detail::check(lq_material_from_json(json.c_str(), &m));
        return Material(m);
    }

    /// Builds a named preset; throws lacquer::Error (LQ_ERR_UNKNOWN_NAME) if there is none.
    static Material preset(const std::string &name) {
        lq_material *m = nullptr;
        detail::check(lq_material_from_preset(name.c_str(), &m));
        return Material(m);
    }

    /// Takes ownership of a handle from lq_material_from_* (must not be NULL).
    explicit Material(lq_material *owned) : m_(owned) {
        if (!m_) {
            throw Error(LQ_ERR_NULL, "Material: NULL handle");
        }
    }

    /// The C handle (borrowed), for calls the wrapper does not cover.
    const lq_material *get() const noexcept { return m_.get(); }

    /// Canonical JSON with every parameter.
    std::string to_json() const {
        char *s = nullptr;
        detail::check(lq_material_to_json(get(), &s));
        return detail::take(s);
    }

    // --- batches through raw pointers (n elements, interleaved; see lacquer.h)

    void eval(std::size_t n, const float *wi, const float *wo, float *f_rgb) const {
        detail::check(lq_eval(get(), n, wi, wo, f_rgb));
    }
    void eval(std::size_t n, const double *wi, const double *wo, double *f_rgb) const {
        detail::check(lq_eval_f64(get(), n, wi, wo, f_rgb));
    }
    void pdf(std::size_t n, const float *wi, const float *wo, float *pdf) const {
        detail::check(lq_pdf(get(), n, wi, wo, pdf));
    }
    void pdf(std::size_t n, const double *wi, const double *wo, double *pdf) const {
        detail::check(lq_pdf_f64(get(), n, wi, wo, pdf));
    }
    void eval_pdf(std::size_t n, const float *wi, const float *wo, float *f_rgb,
                  float *pdf) const {
        detail::check(lq_eval_pdf(get(), n, wi, wo, f_rgb, pdf));
    }
    void sample(std::size_t n, const float *wo, const float *u, float *wi, float *weight_rgb,
                float *pdf, std::uint32_t *flags = nullptr) const {
        detail::check(lq_sample_spatial(get(), n, wo, u, nullptr, nullptr, wi, weight_rgb, pdf,
                                        flags));
    }
    void sample(std::size_t n, const double *wo, const double *u, double *wi,
                double *weight_rgb, double *pdf, std::uint32_t *flags = nullptr) const {
        detail::check(lq_sample_f64(get(), n, wo, u, wi, weight_rgb, pdf, flags));
    }

    // --- length-checked vectors (3 values per direction)

    template <class T>
    std::vector<T> eval(const std::vector<T> &wi, const std::vector<T> &wo) const {
        detail::check_sizes(wi.size(), wo.size(), "wi, wo");
        std::vector<T> f(wi.size());
        eval(wi.size() / 3, wi.data(), wo.data(), f.data());
        return f;
    }
    template <class T>
    std::vector<T> pdf(const std::vector<T> &wi, const std::vector<T> &wo) const {
        detail::check_sizes(wi.size(), wo.size(), "wi, wo");
        std::vector<T> p(wi.size() / 3);
        pdf(wi.size() / 3, wi.data(), wo.data(), p.data());
        return p;
    }

    // --- one element (the cheaper lq_*_one functions, for scalar renderers)

    std::array<float, 3> eval(const std::array<float, 3> &wi,
                              const std::array<float, 3> &wo) const {
        std::array<float, 3> f{};
        detail::check(lq_eval_one(get(), wi.data(), wo.data(), f.data()));
        return f;
    }
    float pdf(const std::array<float, 3> &wi, const std::array<float, 3> &wo) const {
        float p = 0.0f;
        detail::check(lq_pdf_one(get(), wi.data(), wo.data(), &p));
        return p;
    }
    Sample sample(const std::array<float, 3> &wo, const std::array<float, 3> &u) const {
        Sample s;
        detail::check(lq_sample_one(get(), wo.data(), u.data(), s.wi.data(), s.weight.data(),
                                    &s.pdf, &s.flags));
        return s;
    }

    /// Runs the shipped checks on this material (see lq_check_material).
    CheckResult check(lq_check_level level = LQ_CHECK_QUICK) const {
        char *report = nullptr;
        bool passed = false;
        detail::check(lq_check_material(get(), level, &report, &passed));
        CheckResult r;
        r.passed = passed;
        r.report_json = detail::take(report);
        return r;
    }

private:
    struct Deleter {
        void operator()(lq_material *m) const noexcept { lq_material_free(m); }
    };
    std::unique_ptr<lq_material, Deleter> m_;
};

}  // namespace lacquer

#endif  // LACQUER_HPP
