/* Concurrency test of the C ABI (issue 16, docs/reliability.md): THREADS threads each run
 * N evaluations (lq_eval_pdf) and N samples (lq_sample) on materials shared by every thread,
 * and every output must be bit-identical to a run on one thread. Meanwhile two more threads
 * create and free materials (valid and invalid JSON, presets) as fast as they can, checking
 * each new material against the shared one and lq_last_error against the call it follows.
 *
 *   threads [N [THREADS [ROUNDS]]]   default N = 200000, THREADS = 8 (the CI size)
 *   threads 10000000 8               the full size: 8 threads x 1e7 evaluations
 *
 * Each churn round creates one of the four shared materials (in turn) and a preset. Without
 * ROUNDS the churn goes on while the workers run, 20 rounds at least; with ROUNDS (>= 4) each
 * churn thread makes exactly that many, which bounds the run under valgrind: DRD runs one
 * thread at a time, and unbounded churn (paint table builds) kept the workers waiting for
 * 1-134 s from run to run.
 *
 * Inputs are a pure function of the element index, processed in chunks of 4096 elements
 * (every 16th chunk has 40000, so the library's own thread split, >= 32768, runs inside the
 * host's threads too); each chunk's outputs are hashed (FNV-1a over the bits) and compared
 * with the one-thread hash of the same chunk. Each thread starts at a different chunk, so
 * different materials and inputs run at the same moment. Exit status 0 only when every hash
 * matches and no call failed. Also run under valgrind --tool=drd / helgrind by c-api/test.sh
 * with a small N. */
#define _POSIX_C_SOURCE 200809L /* clock_gettime under -std=c99 */
#include <lacquer.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define SMALL 4096
#define LARGE 40000
#define N_MATERIALS 4

static const char *const MATERIAL_JSON[N_MATERIALS] = {
    "{\"preset\": \"gold_flake_8\"}",
    "{\"preset\": \"solid_red\"}",
    "{\"model\": \"rough_conductor\", \"alpha_u\": 0.05, \"alpha_v\": 0.2}",
    "{\"model\": \"coated_paint\"}",
};

static lq_material *shared[N_MATERIALS];
static size_t n_per_thread, n_chunks, min_rounds = 20, max_rounds = SIZE_MAX;
static size_t *chunk_start, *chunk_len;
static uint64_t *reference;
static volatile int workers_done; /* written once by main after joining the workers */
static pthread_mutex_t done_lock = PTHREAD_MUTEX_INITIALIZER;

static uint64_t splitmix(uint64_t x) {
    x += 0x9e3779b97f4a7c15ull;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
    return x ^ (x >> 31);
}

static float unit(uint64_t h) { return (float)((h >> 40) * (1.0 / 16777216.0)); } /* [0, 1) */

/* Element i: wi, wo (upper hemisphere, not normalised: the library normalises) and u. */
static void inputs(size_t i, float *wi, float *wo, float *u) {
    for (int k = 0; k < 3; k++) {
        uint64_t a = splitmix(9 * (uint64_t)i + (uint64_t)k);
        uint64_t b = splitmix(9 * (uint64_t)i + 3 + (uint64_t)k);
        uint64_t c = splitmix(9 * (uint64_t)i + 6 + (uint64_t)k);
        wi[k] = k == 2 ? 0.05f + unit(a) : 2.0f * unit(a) - 1.0f;
        wo[k] = k == 2 ? 0.05f + unit(b) : 2.0f * unit(b) - 1.0f;
        u[k] = unit(c);
    }
}

static uint64_t fnv(uint64_t h, const void *p, size_t bytes) {
    const unsigned char *c = p;
    for (size_t i = 0; i < bytes; i++) h = (h ^ c[i]) * 0x100000001b3ull;
    return h;
}

typedef struct {
    float *wi, *wo, *u, *f, *pdf, *swi, *sw, *spdf;
} buffers;

static int alloc_buffers(buffers *b) {
    b->wi = malloc(3 * LARGE * sizeof(float));
    b->wo = malloc(3 * LARGE * sizeof(float));
    b->u = malloc(3 * LARGE * sizeof(float));
    b->f = malloc(3 * LARGE * sizeof(float));
    b->pdf = malloc(LARGE * sizeof(float));
    b->swi = malloc(3 * LARGE * sizeof(float));
    b->sw = malloc(3 * LARGE * sizeof(float));
    b->spdf = malloc(LARGE * sizeof(float));
    return b->wi && b->wo && b->u && b->f && b->pdf && b->swi && b->sw && b->spdf;
}

static void free_buffers(buffers *b) {
    free(b->wi), free(b->wo), free(b->u), free(b->f), free(b->pdf), free(b->swi), free(b->sw), free(b->spdf);
}

/* Runs chunk c on the shared material it belongs to; returns its hash (0 on a failed call). */
static uint64_t run_chunk(size_t c, buffers *b) {
    size_t n = chunk_len[c], s = chunk_start[c];
    for (size_t j = 0; j < n; j++) inputs(s + j, b->wi + 3 * j, b->wo + 3 * j, b->u + 3 * j);
    const lq_material *m = shared[c % N_MATERIALS];
    if (lq_eval_pdf(m, n, b->wi, b->wo, b->f, b->pdf) != LQ_OK ||
        lq_sample(m, n, b->wo, b->u, b->swi, b->sw, b->spdf) != LQ_OK) {
        fprintf(stderr, "chunk %zu: %s\n", c, lq_last_error());
        return 0;
    }
    uint64_t h = 0xcbf29ce484222325ull;
    h = fnv(h, b->f, 3 * n * sizeof(float));
    h = fnv(h, b->pdf, n * sizeof(float));
    h = fnv(h, b->swi, 3 * n * sizeof(float));
    h = fnv(h, b->sw, 3 * n * sizeof(float));
    h = fnv(h, b->spdf, n * sizeof(float));
    return h;
}

typedef struct {
    int id;
    size_t mismatches, failures;
} worker_arg;

static void *worker(void *p) {
    worker_arg *a = p;
    buffers b;
    if (!alloc_buffers(&b)) {
        a->failures++;
        return NULL;
    }
    size_t first = (size_t)a->id * (n_chunks / 8 + 1);
    for (size_t k = 0; k < n_chunks; k++) {
        size_t c = (first + k) % n_chunks;
        uint64_t h = run_chunk(c, &b);
        if (h == 0) a->failures++;
        else if (h != reference[c]) {
            if (a->mismatches++ == 0) fprintf(stderr, "thread %d: chunk %zu differs from one thread\n", a->id, c);
        }
    }
    free_buffers(&b);
    return NULL;
}

typedef struct {
    int id;
    size_t created, failures;
} churn_arg;

/* Creates and frees materials: until the workers are done and min_rounds are made, or
 * max_rounds. */
static void *churn(void *p) {
    churn_arg *a = p;
    float wi[3] = {0.3f, 0.2f, 0.9f}, wo[3] = {-0.4f, 0.1f, 0.8f}, f_new[3], f_shared[3];
    for (size_t round = 0;; round++) {
        pthread_mutex_lock(&done_lock);
        int done = workers_done;
        pthread_mutex_unlock(&done_lock);
        if ((done && round >= min_rounds) || round >= max_rounds) break;
        int k = (int)((round + (size_t)a->id) % N_MATERIALS);
        lq_material *m = NULL;
        if (lq_material_from_json(MATERIAL_JSON[k], &m) != LQ_OK || strcmp(lq_last_error(), "") != 0) {
            a->failures++;
            continue;
        }
        if (lq_eval_one(m, wi, wo, f_new) != LQ_OK || lq_eval_one(shared[k], wi, wo, f_shared) != LQ_OK ||
            memcmp(f_new, f_shared, sizeof f_new) != 0)
            a->failures++;
        lq_material_free(m);
        a->created++;
        /* An invalid material: an error whose message belongs to this thread's call. */
        lq_material *bad = NULL;
        if (lq_material_from_json("{\"model\": \"lambert\", \"albedo\": 7}", &bad) != LQ_ERR_INVALID_MATERIAL ||
            bad != NULL || strstr(lq_last_error(), "albedo") == NULL)
            a->failures++;
        if (lq_material_from_preset("white_lambert", &m) != LQ_OK) a->failures++;
        else lq_material_free(m), a->created++;
    }
    return NULL;
}

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

int main(int argc, char **argv) {
    n_per_thread = argc > 1 ? (size_t)strtoull(argv[1], NULL, 10) : 200000;
    int n_threads = argc > 2 ? atoi(argv[2]) : 8;
    if (argc > 3) min_rounds = max_rounds = (size_t)strtoull(argv[3], NULL, 10);
    if (n_per_thread < SMALL || n_threads < 1 || n_threads > 64 || min_rounds < N_MATERIALS) {
        fprintf(stderr, "usage: threads [N >= %d [THREADS 1..64 [ROUNDS >= %d]]]\n", SMALL, N_MATERIALS);
        return 2;
    }
    for (int k = 0; k < N_MATERIALS; k++) {
        if (lq_material_from_json(MATERIAL_JSON[k], &shared[k]) != LQ_OK) {
            fprintf(stderr, "%s: %s\n", MATERIAL_JSON[k], lq_last_error());
            return 1;
        }
    }
    /* Chunk layout: 4096 elements, every 16th 40000, until N. */
    size_t cap = n_per_thread / SMALL + 2;
    chunk_start = malloc(cap * sizeof(size_t));
    chunk_len = malloc(cap * sizeof(size_t));
    reference = malloc(cap * sizeof(uint64_t));
    if (!chunk_start || !chunk_len || !reference) return 1;
    for (size_t s = 0; s < n_per_thread; n_chunks++) {
        size_t len = n_chunks % 16 == 15 ? LARGE : SMALL;
        if (len > n_per_thread - s) len = n_per_thread - s;
        chunk_start[n_chunks] = s, chunk_len[n_chunks] = len;
        s += len;
    }
    double t0 = now();
    buffers b;
    if (!alloc_buffers(&b)) return 1;
    for (size_t c = 0; c < n_chunks; c++) {
        reference[c] = run_chunk(c, &b);
        if (reference[c] == 0) return 1;
    }
    free_buffers(&b);
    double t1 = now();

    pthread_t tw[64], tc[2];
    worker_arg wa[64];
    churn_arg ca[2];
    for (int k = 0; k < 2; k++) {
        ca[k] = (churn_arg){k, 0, 0};
        if (pthread_create(&tc[k], NULL, churn, &ca[k]) != 0) return 1;
    }
    for (int t = 0; t < n_threads; t++) {
        wa[t] = (worker_arg){t, 0, 0};
        if (pthread_create(&tw[t], NULL, worker, &wa[t]) != 0) return 1;
    }
    size_t mismatches = 0, failures = 0, created = 0;
    for (int t = 0; t < n_threads; t++) {
        pthread_join(tw[t], NULL);
        mismatches += wa[t].mismatches, failures += wa[t].failures;
    }
    double t2 = now();
    pthread_mutex_lock(&done_lock);
    workers_done = 1;
    pthread_mutex_unlock(&done_lock);
    for (int k = 0; k < 2; k++) {
        pthread_join(tc[k], NULL);
        failures += ca[k].failures, created += ca[k].created;
    }
    for (int k = 0; k < N_MATERIALS; k++) lq_material_free(shared[k]);
    free(chunk_start), free(chunk_len), free(reference);

    printf("threads: %d x %zu evaluations + %zu samples on %d shared materials (%zu chunks): "
           "one thread %.2f s, %d threads %.2f s; %zu chunk mismatches, %zu failed calls; "
           "%zu materials created and freed concurrently\n",
           n_threads, n_per_thread, n_per_thread, N_MATERIALS, n_chunks, t1 - t0, n_threads, t2 - t1, mismatches,
           failures, created);
    return mismatches == 0 && failures == 0 && created > 0 ? 0 : 1;
}
