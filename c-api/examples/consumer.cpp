// A C++17 host of liblacquer through lacquer.hpp (RAII + exceptions): loads a preset,
// evaluates, samples, checks, handles errors, and evaluates one material from 8 threads.
// Built by c-api/test.sh against the installed files and run under valgrind.
#include <lacquer.hpp>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <string>
#include <thread>
#include <vector>

static int passed = 0, failed = 0;

#define CHECK(cond, what)                                                              \
    do {                                                                               \
        if (cond) {                                                                    \
            passed++;                                                                  \
        } else {                                                                       \
            failed++;                                                                  \
            std::cerr << "FAIL " << __FILE__ << ":" << __LINE__ << ": " << #cond << ": " \
                      << what << "\n";                                                 \
        }                                                                              \
    } while (0)

// Expects `body` to throw lacquer::Error with `status`; returns its message.
template <class F>
static std::string expect_error(lq_status status, F body) {
    try {
        body();
    } catch (const lacquer::Error &e) {
        CHECK(e.status() == status, e.what());
        return e.what();
    }
    CHECK(false, "no exception");
    return {};
}

int main() {
    const double pi = 3.14159265358979323846;
    lacquer::check_abi();
    std::cout << "liblacquer " << lacquer::version() << "\n";
    CHECK(lacquer::models_json().find("\"lambert\"") != std::string::npos, "models");
    CHECK(lacquer::presets_json().find("\"white_lambert\"") != std::string::npos, "presets");

    // A preset; single-element calls.
    const lacquer::Material white = lacquer::Material::preset("white_lambert");
    const auto f = white.eval({0.f, 0.6f, 0.8f}, {0.f, 0.f, 1.f});
    CHECK(std::fabs(f[0] - 1 / pi) < 1e-6 && f[1] == f[0] && f[2] == f[0], f[0]);
    CHECK(std::fabs(white.pdf({0.f, 0.6f, 0.8f}, {0.f, 0.f, 1.f}) - 0.8 / pi) < 1e-6, "pdf");
    const lacquer::Sample s = white.sample({0.f, 0.f, 1.f}, {0.1f, 0.2f, 0.3f});
    CHECK(s.pdf > 0 && s.flags == 0 && std::fabs(s.weight[0] - 1.0f) < 1e-5, s.pdf);
    CHECK(std::fabs(white.pdf(s.wi, {0.f, 0.f, 1.f}) - s.pdf) < 1e-4 * s.pdf, "sample pdf");

    // Vector batches in double precision.
    const std::vector<double> wi = {0, 0, 1, 0.6, 0, 0.8}, wo = {0, 0, 1, 0, 0, 1};
    const std::vector<double> fv = white.eval(wi, wo);
    CHECK(fv.size() == 6 && std::fabs(fv[3] - 1 / pi) < 1e-15, fv[3]);

    // JSON material, canonical JSON, move semantics.
    lacquer::Material red = lacquer::Material::from_json(R"({"model": "lambert", "albedo": [0.9, 0.1, 0.1]})");
    const std::string canon = red.to_json();
    CHECK(canon.find("\"albedo\"") != std::string::npos, canon);
    lacquer::Material moved = std::move(red);
    CHECK(moved.get() != nullptr, "moved handle");
    const lacquer::CheckResult chk = moved.check(LQ_CHECK_QUICK);
    CHECK(chk.passed && chk.report_json.find("reciprocity") != std::string::npos, "check");

    // Errors become exceptions with the status and the library's message.
    std::string msg = expect_error(LQ_ERR_INVALID_JSON, [] { lacquer::Material::from_json("{\"model\""); });
    std::cout << "truncated JSON -> " << msg << "\n";
    msg = expect_error(LQ_ERR_INVALID_MATERIAL,
                       [] { lacquer::Material::from_json(R"({"model": "lambert", "albedo": 2})"); });
    CHECK(msg.find("albedo") != std::string::npos, msg);
    expect_error(LQ_ERR_UNKNOWN_NAME, [] { lacquer::Material::preset("nope"); });
    expect_error(LQ_ERR_INVALID_ARGUMENT, [&] { white.eval(std::vector<float>(6), std::vector<float>(3)); });
    // Per-element: outputs are written before the throw.
    float nan_wi[6] = {0, 0, 1, NAN, 0, 1}, up[6] = {0, 0, 1, 0, 0, 1}, out[6] = {-1, -1, -1, -1, -1, -1};
    try {
        white.eval(2, nan_wi, up, out);
        CHECK(false, "no exception");
    } catch (const lacquer::Error &e) {
        CHECK(e.status() == LQ_ERR_INVALID_DIRECTION && e.outputs_written(), e.what());
        CHECK(out[3] == 0 && std::fabs(out[0] - 1 / pi) < 1e-6, out[0]);
    }

    // One material, 8 threads: identical results to one thread.
    const std::size_t n = 20000;
    std::vector<float> bwi(3 * n), bwo(3 * n);
    for (std::size_t i = 0; i < n; i++) {
        const float a = 0.001f * i, b = 0.0007f * i;
        bwi[3 * i] = std::sin(a), bwi[3 * i + 1] = 0.1f, bwi[3 * i + 2] = std::cos(a);
        bwo[3 * i] = 0.2f, bwo[3 * i + 1] = std::sin(b), bwo[3 * i + 2] = std::cos(b);
    }
    const std::vector<float> reference = moved.eval(bwi, bwo);
    std::vector<std::vector<float>> results(8);
    std::vector<std::thread> threads;
    for (int t = 0; t < 8; t++) {
        threads.emplace_back([&, t] { results[t] = moved.eval(bwi, bwo); });
    }
    for (auto &th : threads) th.join();
    for (int t = 0; t < 8; t++) {
        CHECK(results[t] == reference, "thread " << t << " differs");
    }

    std::printf("c++ consumer: %d passed, %d failed\n", passed, failed);
    return failed == 0 ? 0 : 1;
}
