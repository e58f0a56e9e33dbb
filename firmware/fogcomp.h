/* fogcomp.h: reference implementation of fogbench's drift compensation for a gyro's firmware.
 *
 * C99, one header, no allocation, fixed-size state, no libm beyond exp(). The model comes from
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
  FOGCOMP_WARM    /* exp(-max(a, 0) / p) */
};

typedef struct {
  int kind; /* enum fogcomp_kind */
  int a, b; /* inputs: indices of earlier operations, -1 when unused */
  int n;    /* signal index, window or delay length (samples), power */
  double p; /* number, lp's alpha, warm's tau (s) */
  int ring; /* slope, delay: offset of its history in fogcomp_state.ring */
} fogcomp_op;

typedef struct {
  double dt_s;    /* sample interval the model was compiled for, s */
  double tref_c;  /* temperatures enter as T - tref_c, degC */
  double mu0_dph; /* constant bias, deg/h */
  int n_ops;
  fogcomp_op ops[FOGCOMP_MAX_OPS];
  int n_terms;
  int term_op[FOGCOMP_MAX_TERMS]; /* the operation whose value is term j */
  double beta[FOGCOMP_MAX_TERMS]; /* deg/h per unit of term j */
  int ring_size;                  /* doubles of history used */
} fogcomp_model;

typedef struct {
  double t1_c, t2_c, ta_c; /* coil centre, coil outer wall, chamber air: degC */
  double ton_s;            /* time since the gyro's power-on, s */
} fogcomp_input;

typedef struct {
  double value[FOGCOMP_MAX_OPS];
  double state[FOGCOMP_MAX_OPS];
  int pos[FOGCOMP_MAX_OPS];
  double ring[FOGCOMP_MAX_RING];
  int started;
} fogcomp_state;

static void fogcomp_init(fogcomp_state* s) {
  int k;
  for (k = 0; k < FOGCOMP_MAX_OPS; ++k) {
    s->value[k] = 0.0;
    s->state[k] = 0.0;
    s->pos[k] = 0;
  }
  s->started = 0;
}

/* Returns 0 when the model fits this build's sizes and its operations are well formed. */
static int fogcomp_check(const fogcomp_model* m) {
  int k;
  if (m->n_ops < 0 || m->n_ops > FOGCOMP_MAX_OPS || m->n_terms < 0 || m->n_terms > FOGCOMP_MAX_TERMS ||
      m->ring_size < 0 || m->ring_size > FOGCOMP_MAX_RING || !(m->dt_s > 0.0))
    return -1;
  for (k = 0; k < m->n_ops; ++k) {
    const fogcomp_op* o = &m->ops[k];
    if (o->a >= k || o->b >= k) return -1;
    if ((o->kind == FOGCOMP_SLOPE || o->kind == FOGCOMP_DELAY) &&
        (o->n < 1 || o->ring < 0 || o->ring + o->n > m->ring_size))
      return -1;
  }
  for (k = 0; k < m->n_terms; ++k)
    if (m->term_op[k] < 0 || m->term_op[k] >= m->n_ops) return -1;
  return 0;
}

/* The drift mu(t) of this sample, deg/h. */
static double fogcomp_step(fogcomp_state* s, const fogcomp_model* m, const fogcomp_input* in) {
  const int first = !s->started;
  double mu;
  int k, j;
  s->started = 1;
  for (k = 0; k < m->n_ops; ++k) {
    const fogcomp_op* o = &m->ops[k];
    const double a = o->a >= 0 ? s->value[o->a] : 0.0;
    const double b = o->b >= 0 ? s->value[o->b] : 0.0;
    double v = 0.0;
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
        double* h = s->ring + o->ring;
        if (first)
          for (j = 0; j < o->n; ++j) h[j] = a;
        if (o->kind == FOGCOMP_DELAY) {
          v = h[s->pos[k]];
          h[s->pos[k]] = a;
          s->pos[k] = (s->pos[k] + 1) % o->n;
        } else {
          const double c = 0.5 * (o->n - 1);
          double num = 0.0, den = 0.0;
          h[s->pos[k]] = a;
          s->pos[k] = (s->pos[k] + 1) % o->n;
          for (j = 0; j < o->n; ++j) {
            num += (j - c) * h[(s->pos[k] + j) % o->n];
            den += (j - c) * (j - c);
          }
          v = num / den * 60.0 / m->dt_s;
        }
        break;
      }
      case FOGCOMP_LP:
        if (first) s->state[k] = a;
        v = s->state[k] = s->state[k] + o->p * (a - s->state[k]);
        break;
      case FOGCOMP_UP: v = a > 0.0 ? a : 0.0; break;
      case FOGCOMP_DOWN: v = a < 0.0 ? a : 0.0; break;
      case FOGCOMP_POW:
        v = a;
        for (j = 1; j < o->n; ++j) v *= a;
        break;
      case FOGCOMP_NEG: v = -a; break;
      case FOGCOMP_ADD: v = a + b; break;
      case FOGCOMP_SUB: v = a - b; break;
      case FOGCOMP_MUL: v = a * b; break;
      case FOGCOMP_WARM: v = exp(-(a > 0.0 ? a : 0.0) / o->p); break;
      default: v = 0.0; break;
    }
    s->value[k] = v;
  }
  mu = m->mu0_dph;
  for (k = 0; k < m->n_terms; ++k) mu += m->beta[k] * s->value[m->term_op[k]];
  return mu;
}

#endif /* FOGCOMP_H */
