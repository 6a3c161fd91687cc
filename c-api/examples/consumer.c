/* A C99 host of liblacquer: loads a preset and a JSON material, evaluates, samples, runs the
 * checks, and handles every kind of error. Built by c-api/test.sh against the INSTALLED
 * header and library (pkg-config lacquer, and lacquer-static), and run under valgrind.
 * Exit status 0 when every check passes. */
#include <lacquer.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int passed = 0, failed = 0;

#define CHECK(cond, ...)                                                   \
    do {                                                                   \
        if (cond) {                                                        \
            passed++;                                                      \
        } else {                                                           \
            failed++;                                                      \
            fprintf(stderr, "FAIL %s:%d: %s: ", __FILE__, __LINE__, #cond); \
            fprintf(stderr, __VA_ARGS__);                                  \
            fprintf(stderr, "\n");                                         \
        }                                                                  \
    } while (0)

/* A small deterministic generator for u in [0, 1). */
static unsigned long long rng_state = 0x853c49e6748fea9bULL;
static float uniform(void) {
    rng_state = rng_state * 6364136223846793005ULL + 1442695040888963407ULL;
    return (float)((rng_state >> 40) * (1.0 / 16777216.0));
}

int main(void) {
    const double pi = 3.14159265358979323846;
    lq_status s;

    /* Versions: header and library must agree. */
    unsigned abi = lq_abi_version();
    CHECK((abi >> 16) == LQ_ABI_VERSION_MAJOR && (abi & 0xffff) >= LQ_ABI_VERSION_MINOR,
          "library ABI %u.%u, header %d.%d", abi >> 16, abi & 0xffff, LQ_ABI_VERSION_MAJOR,
          LQ_ABI_VERSION_MINOR);
    printf("liblacquer %s, ABI %u.%u\n", lq_version(), abi >> 16, abi & 0xffff);

    /* Model and preset lists. */
    char *models = NULL, *presets = NULL;
    s = lq_models_json(&models);
    CHECK(s == LQ_OK && models && strstr(models, "\"lambert\""), "%s", lq_last_error());
    s = lq_presets_json(&presets);
    CHECK(s == LQ_OK && presets && strstr(presets, "\"white_lambert\""), "%s", lq_last_error());
    printf("models: %zu bytes of JSON, presets: %zu bytes\n", strlen(models), strlen(presets));
    lq_string_free(models);
    lq_string_free(presets);

    /* A preset: the lossless diffuse reflector, f = 1/pi. */
    lq_material *white = NULL;
    s = lq_material_from_preset("white_lambert", &white);
    CHECK(s == LQ_OK && white != NULL, "%s", lq_last_error());

    enum { N = 4 };
    const float wi[3 * N] = {0, 0, 1, 0.6f, 0, 0.8f, 0, -0.6f, 0.8f, 0.3f, 0.4f, -0.866f};
    const float wo[3 * N] = {0, 0, 1, 0, 0, 1, 0.48f, 0.6f, 0.64f, 0, 0, 1};
    float f[3 * N], pdf[N];
    s = lq_eval_pdf(white, N, wi, wo, f, pdf);
    CHECK(s == LQ_OK, "%s", lq_last_error());
    for (int i = 0; i < 3; i++) {
        CHECK(fabs(f[3 * i] - 1.0 / pi) < 1e-6 && f[3 * i + 1] == f[3 * i] &&
                  f[3 * i + 2] == f[3 * i],
              "f[%d] = %g, expected 1/pi", i, f[3 * i]);
        CHECK(fabs(pdf[i] - wi[3 * i + 2] / pi) < 1e-6, "pdf[%d] = %g", i, pdf[i]);
    }
    CHECK(f[9] == 0 && pdf[3] == 0, "below the horizon: f = %g, pdf = %g", f[9], pdf[3]);

    /* One element, the cheap path for scalar renderers; in place is allowed. */
    float one[3] = {0, 0.6f, 0.8f};
    s = lq_eval_one(white, one, wo, one);
    CHECK(s == LQ_OK && fabs(one[0] - 1.0 / pi) < 1e-6, "lq_eval_one: %g", one[0]);

    /* Double precision. */
    const double wi64[3] = {0, 0.6, 0.8}, wo64[3] = {0, 0, 1};
    double f64[3];
    s = lq_eval_f64(white, 1, wi64, wo64, f64);
    CHECK(s == LQ_OK && fabs(f64[0] - 1.0 / pi) < 1e-15, "f64 = %.17g", f64[0]);

    /* A JSON material, sampled: for Lambert the weight is the albedo, and sample's pdf
     * equals lq_pdf at the sampled direction. */
    lq_material *grey = NULL;
    s = lq_material_from_json("{\"model\": \"lambert\", \"albedo\": [0.8, 0.5, 0.2]}", &grey);
    CHECK(s == LQ_OK, "%s", lq_last_error());
    enum { S = 1000 };
    float *swo = malloc(sizeof(float) * 3 * S), *u = malloc(sizeof(float) * 3 * S);
    float *swi = malloc(sizeof(float) * 3 * S), *weight = malloc(sizeof(float) * 3 * S);
    float *spdf = malloc(sizeof(float) * S), *check_pdf = malloc(sizeof(float) * S);
    for (int i = 0; i < S; i++) {
        swo[3 * i] = 0.3f;
        swo[3 * i + 1] = -0.2f;
        swo[3 * i + 2] = 0.9f; /* not unit length: the library normalises */
        for (int k = 0; k < 3; k++) u[3 * i + k] = uniform();
    }
    s = lq_sample(grey, S, swo, u, swi, weight, spdf);
    CHECK(s == LQ_OK, "%s", lq_last_error());
    s = lq_pdf(grey, S, swi, swo, check_pdf);
    CHECK(s == LQ_OK, "%s", lq_last_error());
    int bad = 0;
    for (int i = 0; i < S; i++) {
        if (!(spdf[i] > 0) || fabs(spdf[i] - check_pdf[i]) > 1e-4 * check_pdf[i] ||
            fabs(weight[3 * i] - 0.8f) > 1e-5 || fabs(weight[3 * i + 2] - 0.2f) > 1e-5 ||
            !(swi[3 * i + 2] > 0))
            bad++;
    }
    CHECK(bad == 0, "%d of %d samples inconsistent", bad, S);
    free(swo), free(u), free(swi), free(weight), free(spdf), free(check_pdf);

    /* The shipped checks, through the ABI. */
    char *report = NULL;
    bool ok = false;
    s = lq_check_material(grey, LQ_CHECK_QUICK, &report, &ok);
    CHECK(s == LQ_OK && ok && report && strstr(report, "\"verdicts\""), "%s", lq_last_error());
    lq_string_free(report);

    /* Errors: each gives a status and a message, and leaves the out-parameter alone. */
    lq_material *m = NULL;
    s = lq_material_from_json("{\"model\": \"lambert\", \"albedo\": 0.", &m);
    CHECK(s == LQ_ERR_INVALID_JSON && m == NULL && strlen(lq_last_error()) > 0, "status %d", s);
    printf("truncated JSON -> %s: %s\n", lq_status_name(s), lq_last_error());
    s = lq_material_from_json("{\"model\": \"lambert\", \"albedo\": -0.5}", &m);
    CHECK(s == LQ_ERR_INVALID_MATERIAL && m == NULL && strstr(lq_last_error(), "albedo"),
          "status %d: %s", s, lq_last_error());
    printf("negative albedo -> %s: %s\n", lq_status_name(s), lq_last_error());
    s = lq_material_from_json("{\"model\": \"lambert\", \"roughness\": 0.1}", &m);
    CHECK(s == LQ_ERR_INVALID_MATERIAL && strstr(lq_last_error(), "roughness"), "status %d", s);
    s = lq_material_from_preset("no such preset", &m);
    CHECK(s == LQ_ERR_UNKNOWN_NAME && m == NULL, "status %d", s);
    s = lq_eval(NULL, 1, wi, wo, f);
    CHECK(s == LQ_ERR_NULL, "status %d", s);
    s = lq_eval(white, 1, NULL, wo, f);
    CHECK(s == LQ_ERR_NULL && strstr(lq_last_error(), "wi"), "%s", lq_last_error());
    s = lq_eval(white, 0, NULL, NULL, NULL);
    CHECK(s == LQ_OK && lq_last_error()[0] == '\0', "n = 0: status %d", s);

    /* A NaN direction: that element is 0, the others are evaluated, the status says so. */
    float nan_wi[6] = {0, 0, 1, NAN, 0, 1}, two_wo[6] = {0, 0, 1, 0, 0, 1}, f2[6];
    s = lq_eval(white, 2, nan_wi, two_wo, f2);
    CHECK(s == LQ_ERR_INVALID_DIRECTION && f2[3] == 0 && fabs(f2[0] - 1.0 / pi) < 1e-6,
          "status %d, f = %g %g", s, f2[0], f2[3]);
    printf("NaN direction -> %s: %s\n", lq_status_name(s), lq_last_error());

    /* In-place output is refused before anything is written. */
    float inplace[3] = {0, 0, 1};
    s = lq_eval(white, 1, inplace, wo, inplace);
    CHECK(s == LQ_ERR_INVALID_ARGUMENT && inplace[2] == 1, "status %d", s);


    /* Typed queries: parameter specs, one parameter's value, lobes and diffuse albedo. */
    size_t np = 0;
    s = lq_model_param_count("coated_paint", &np);
    CHECK(s == LQ_OK && np > 10, "coated_paint has %u params: %s", (unsigned)np, lq_last_error());
    int found_density = 0, found_color = 0, found_choice = 0;
    for (size_t i = 0; i < np; ++i) {
        lq_param_spec spec;
        s = lq_model_param("coated_paint", i, &spec);
        CHECK(s == LQ_OK && spec.name && spec.name[0], "param %u: %s", (unsigned)i, lq_last_error());
        if (strcmp(spec.name, "flake_density") == 0)
            found_density = spec.kind == LQ_PARAM_SCALAR && spec.min == 0 && spec.max > spec.min;
        if (strcmp(spec.name, "base_color") == 0)
            found_color = spec.kind == LQ_PARAM_COLOR && spec.max == 1;
        if (strcmp(spec.name, "flake_material") == 0)
            found_choice = spec.kind == LQ_PARAM_CHOICE && strstr(spec.choices, "Al") != NULL &&
                           strcmp(spec.default_text, "Al") == 0;
    }
    CHECK(found_density && found_color && found_choice, "specs: density %d colour %d choice %d",
          found_density, found_color, found_choice);
    lq_param_spec none;
    s = lq_model_param("coated_paint", np, &none);
    CHECK(s == LQ_ERR_INVALID_ARGUMENT, "index past the end: status %d", s);
    s = lq_model_param_count("no_such_model", &np);
    CHECK(s == LQ_ERR_UNKNOWN_NAME, "unknown model: status %d", s);

    uint32_t lobes = 0;
    s = lq_material_lobes(grey, &lobes);
    CHECK(s == LQ_OK && lobes == LQ_LOBE_DIFFUSE, "lambert lobes %u", lobes);
    float albedo[3];
    s = lq_material_diffuse_reflectance(grey, albedo);
    CHECK(s == LQ_OK && fabs(albedo[0] - 0.8) < 1e-6 && fabs(albedo[1] - 0.5) < 1e-6, "albedo %g", albedo[0]);
    lq_material *paint = NULL;
    s = lq_material_from_json("{\"model\": \"coated_paint\", \"coat_roughness\": 0, "
                              "\"base_color\": [0.2, 0.3, 0.4], \"sparkle\": true}", &paint);
    CHECK(s == LQ_OK, "%s", lq_last_error());
    s = lq_material_lobes(paint, &lobes);
    CHECK(s == LQ_OK && (lobes & LQ_LOBE_DIFFUSE) && (lobes & LQ_LOBE_GLOSSY) && (lobes & LQ_LOBE_DELTA) &&
              !(lobes & LQ_LOBE_ANISOTROPIC),
          "smooth-coat paint lobes %u", lobes);
    s = lq_material_diffuse_reflectance(paint, albedo);
    CHECK(s == LQ_OK && fabs(albedo[2] - 0.4) < 1e-6, "paint albedo %g", albedo[2]);
    char *value = NULL;
    s = lq_material_param_json(paint, "base_color", &value);
    CHECK(s == LQ_OK && value && value[0] == '[', "base_color = %s", value ? value : "(null)");
    lq_string_free(value);
    value = NULL;
    s = lq_material_param_json(paint, "flake_densty", &value);
    CHECK(s == LQ_ERR_UNKNOWN_NAME && value == NULL && strstr(lq_last_error(), "flake_density"),
          "misspelt parameter: %s", lq_last_error());
    lq_material_free(paint);
    lq_material *aniso = NULL;
    s = lq_material_from_json("{\"model\": \"rough_conductor\", \"alpha_u\": 0.1, \"alpha_v\": 0.4}", &aniso);
    CHECK(s == LQ_OK, "%s", lq_last_error());
    s = lq_material_lobes(aniso, &lobes);
    CHECK(s == LQ_OK && (lobes & LQ_LOBE_ANISOTROPIC) && (lobes & LQ_LOBE_GLOSSY) && !(lobes & LQ_LOBE_DIFFUSE),
          "anisotropic conductor lobes %u", lobes);
    lq_material_free(aniso);

    lq_material_free(white);
    lq_material_free(grey);
    lq_material_free(NULL);

    printf("c consumer: %d passed, %d failed\n", passed, failed);
    return failed == 0 ? 0 : 1;
}
