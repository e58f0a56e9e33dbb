/* fogcomp.h: reference implementation of fogbench's drift compensation for a gyro's firmware.
 *
 * C99, one header of `static inline` functions (a file that uses some of them compiles clean
 * under -Wall -Wextra -Werror), no allocation, fixed-size state, no libm beyond exp(). Numbers
 * are `fogcomp_real`: double, or float when FOGCOMP_FLOAT is defined before the include (a
 * microcontroller with a single-precision FPU, e.g. a Cortex-M4F: no software doubles, expf();
 * it matches the reference vector to the tolerance docs/firmware.md gives). The model comes from
 * `fogctl coefficients SERIAL --format c` as a `fogcomp_model` initializer; each sample:
 *
 *     fogcomp_state st;                         (one per gyro; about 66 KB with the defaults)
 *     fogcomp_init(&st);
 *     for each sample:  in = {t1_c, t2_c, ta_c, ton_s};
 *                       compensated_dph = gyro_dph - fogcomp_step(&st, &MODEL, &in);
 *
 * The model is a program of operations, each reading earlier ones (fogbench's
 * model/include/fogbench/model/firmware.hpp says what each computes and why the rates are
 * causal slopes). The first sample fills every window, delay and filter (the run opens with a
 * steady hold). Sizes: FOGCOMP_MAX_OPS, FOGCOMP_MAX_TERMS, FOGCOMP_MAX_RING may be lowered to
 * what the models in use need (the `ring_size` and `n_ops` of each model).
 */
#ifndef FOGCOMP_H
#define FOGCOMP_H

#include <math.h>

#ifndef FOGCOMP_MAX_OPS
#define FOGCOMP_MAX_OPS 64
#endif
#ifndef FOGCOMP_MAX_TERMS
#define FOGCOMP_MAX_TERMS 16
#endif
#ifndef FOGCOMP_MAX_RING
#define FOGCOMP_MAX_RING 8192
#endif

#ifdef FOGCOMP_FLOAT
typedef float fogcomp_real;
#define FOGCOMP_EXP expf
#else
typedef double fogcomp_real;
#define FOGCOMP_EXP exp
#endif
/* A constant as fogcomp_real (the generated models write their numbers through it). */
#define FOGCOMP_R(x) ((fogcomp_real)(x))

enum fogcomp_kind {
  FOGCOMP_SIGNAL, /* n: 0 T1, 1 T2, 2 Ta (degC, minus tref_c), 3 time since power-on (s) */
  FOGCOMP_NUMBER, /* p */
  FOGCOMP_SLOPE,  /* least-squares slope of a over its last n samples, per minute */
  FOGCOMP_LP,     /* y += p (a - y) */
  FOGCOMP_DELAY,  /* a, n samples earlier */
  FOGCOMP_UP,     /* max(a, 0) */
  FOGCOMP_DOWN,   /* min(a, 0) */
  FOGCOMP_POW,    /* a^n */
  FOGCOMP_NEG,    /* -a */
  FOGCOMP_ADD,    /* a + b */
  FOGCOMP_SUB,    /* a - b */
  FOGCOMP_MUL,    /* a * b */
  FOGCOMP_WARM,   /* exp(-max(a, 0) / p) */
  FOGCOMP_N_KINDS /* not an operation: the number of kinds */
};

typedef struct {
  int kind; /* enum fogcomp_kind */
  int a, b; /* inputs: indices of earlier operations, -1 when unused */
  int n;    /* signal index, window or delay length (samples), power */
  fogcomp_real p; /* number, lp's alpha, warm's tau (s) */
  int ring; /* slope, delay: offset of its history in fogcomp_state.ring */
} fogcomp_op;

typedef struct {
  fogcomp_real dt_s;    /* sample interval the model was compiled for, s */
  fogcomp_real tref_c;  /* temperatures enter as T - tref_c, degC */
  fogcomp_real mu0_dph; /* constant bias, deg/h */
  int n_ops;
  fogcomp_op ops[FOGCOMP_MAX_OPS];
  int n_terms;
  int term_op[FOGCOMP_MAX_TERMS]; /* the operation whose value is term j */
  fogcomp_real beta[FOGCOMP_MAX_TERMS]; /* deg/h per unit of term j */
  int ring_size;                        /* numbers of history used */
} fogcomp_model;

typedef struct {
  fogcomp_real t1_c, t2_c, ta_c; /* coil centre, coil outer wall, chamber air: degC */
  fogcomp_real ton_s;            /* time since the gyro's power-on, s */
} fogcomp_input;

typedef struct {
  fogcomp_real value[FOGCOMP_MAX_OPS];
  fogcomp_real state[FOGCOMP_MAX_OPS];
  int pos[FOGCOMP_MAX_OPS];
  fogcomp_real ring[FOGCOMP_MAX_RING];
  int started;
} fogcomp_state;

static inline void fogcomp_init(fogcomp_state* s) {
  int k;
  for (k = 0; k < FOGCOMP_MAX_OPS; ++k) {
    s->value[k] = FOGCOMP_R(0);
    s->state[k] = FOGCOMP_R(0);
    s->pos[k] = 0;
  }
  s->started = 0;
}

/* Returns 0 when the model fits this build's sizes and its operations are well formed: a known
 * kind, inputs that are earlier operations (and present where the kind reads them), a signal
 * index 0..3, a power 1..4, a window or delay inside the history pool, an lp alpha in (0, 1],
 * a warm time constant > 0 s (a zero one would divide by zero), a sample interval > 0 s. */
static inline int fogcomp_check(const fogcomp_model* m) {
  int k;
  if (m->n_ops < 0 || m->n_ops > FOGCOMP_MAX_OPS || m->n_terms < 0 || m->n_terms > FOGCOMP_MAX_TERMS ||
      m->ring_size < 0 || m->ring_size > FOGCOMP_MAX_RING || !(m->dt_s > FOGCOMP_R(0)))
    return -1;
  for (k = 0; k < m->n_ops; ++k) {
    const fogcomp_op* o = &m->ops[k];
    const int reads_a = o->kind != FOGCOMP_SIGNAL && o->kind != FOGCOMP_NUMBER;
    const int reads_b = o->kind == FOGCOMP_ADD || o->kind == FOGCOMP_SUB || o->kind == FOGCOMP_MUL;
    if (o->kind < 0 || o->kind >= FOGCOMP_N_KINDS) return -1;
    if (o->a >= k || o->b >= k || (reads_a && o->a < 0) || (reads_b && o->b < 0)) return -1;
    if (o->kind == FOGCOMP_SIGNAL && (o->n < 0 || o->n > 3)) return -1;
    if (o->kind == FOGCOMP_POW && (o->n < 1 || o->n > 4)) return -1;
    if ((o->kind == FOGCOMP_SLOPE || o->kind == FOGCOMP_DELAY) &&
        (o->n < 1 || o->ring < 0 || o->ring + o->n > m->ring_size))
      return -1;
    if (o->kind == FOGCOMP_SLOPE && o->n < 2) return -1;
    if (o->kind == FOGCOMP_LP && !(o->p > FOGCOMP_R(0) && o->p <= FOGCOMP_R(1))) return -1;
    if (o->kind == FOGCOMP_WARM && !(o->p > FOGCOMP_R(0))) return -1;
  }
  for (k = 0; k < m->n_terms; ++k)
    if (m->term_op[k] < 0 || m->term_op[k] >= m->n_ops) return -1;
  return 0;
}

/* The drift mu(t) of this sample, deg/h. The model must have passed fogcomp_check(). */
static inline fogcomp_real fogcomp_step(fogcomp_state* s, const fogcomp_model* m, const fogcomp_input* in) {
  const int first = !s->started;
  fogcomp_real mu;
  int k, j;
  s->started = 1;
  for (k = 0; k < m->n_ops; ++k) {
    const fogcomp_op* o = &m->ops[k];
    const fogcomp_real a = o->a >= 0 ? s->value[o->a] : FOGCOMP_R(0);
    const fogcomp_real b = o->b >= 0 ? s->value[o->b] : FOGCOMP_R(0);
    fogcomp_real v = FOGCOMP_R(0);
    switch (o->kind) {
      case FOGCOMP_SIGNAL:
        v = o->n == 0 ? in->t1_c - m->tref_c
          : o->n == 1 ? in->t2_c - m->tref_c
          : o->n == 2 ? in->ta_c - m->tref_c
          : in->ton_s;
        break;
      case FOGCOMP_NUMBER: v = o->p; break;
      case FOGCOMP_SLOPE:
      case FOGCOMP_DELAY: {
        fogcomp_real* h = s->ring + o->ring;
        if (first)
          for (j = 0; j < o->n; ++j) h[j] = a;
        if (o->kind == FOGCOMP_DELAY) {
          v = h[s->pos[k]];
          h[s->pos[k]] = a;
          s->pos[k] = (s->pos[k] + 1) % o->n;
        } else {
          /* sum (j - c) x_j / sum (j - c)^2 with c = (n - 1) / 2, in half-steps (2j - n + 1) so
           * that the weights are whole numbers: exact in float as in double */
          fogcomp_real num = FOGCOMP_R(0), den = FOGCOMP_R(0);
          h[s->pos[k]] = a;
          s->pos[k] = (s->pos[k] + 1) % o->n;
          for (j = 0; j < o->n; ++j) {
            const fogcomp_real w = (fogcomp_real)(2 * j - o->n + 1);
            num += w * h[(s->pos[k] + j) % o->n];
            den += w * w;
          }
          v = FOGCOMP_R(2) * num / den * (FOGCOMP_R(60) / m->dt_s);
        }
        break;
      }
      case FOGCOMP_LP:
        if (first) s->state[k] = a;
        v = s->state[k] = s->state[k] + o->p * (a - s->state[k]);
        break;
      case FOGCOMP_UP: v = a > FOGCOMP_R(0) ? a : FOGCOMP_R(0); break;
      case FOGCOMP_DOWN: v = a < FOGCOMP_R(0) ? a : FOGCOMP_R(0); break;
      case FOGCOMP_POW:
        v = a;
        for (j = 1; j < o->n; ++j) v *= a;
        break;
      case FOGCOMP_NEG: v = -a; break;
      case FOGCOMP_ADD: v = a + b; break;
      case FOGCOMP_SUB: v = a - b; break;
      case FOGCOMP_MUL: v = a * b; break;
      case FOGCOMP_WARM: v = FOGCOMP_EXP(-(a > FOGCOMP_R(0) ? a : FOGCOMP_R(0)) / o->p); break;
      default: v = FOGCOMP_R(0); break;
    }
    s->value[k] = v;
  }
  mu = m->mu0_dph;
  for (k = 0; k < m->n_terms; ++k) mu += m->beta[k] * s->value[m->term_op[k]];
  return mu;
}

#endif /* FOGCOMP_H */
