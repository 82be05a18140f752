/* Lanes: 16 samples at once, for the collision filter's path and configuration checks.
 *
 * Each lane holds one sample of a linear joint path (its own path: start, change, path
 * parameter t, per-pair rates; a configuration is a path that does not move) and gets a
 * step s >= 0 such that every candidate pair of the scene stays farther than its contact
 * margin for |t' - t| <= s along that path, from lower bounds only; or CONTACT (-2) where
 * a witness proves a pair in contact (witness below); or -1 where neither is proven (the
 * caller then decides that sample exactly). s never exceeds the lane's cap.
 *
 * The bounds: each moving geom's container is held by spheres on its axis (a capsule's or
 * cylinder's, a sphere itself: "covers", lanes.py); the distance of a cover sphere's
 * centre to the partner's container (a point to a sphere, capsule, box, cylinder or
 * half-space, in closed form) less its radius bounds the pair's distance from below, and
 * so does the gap of the two bounding spheres. A pair closes at most at its rate (m per
 * unit t, as the scalar kernels use it), so a gap g beyond the margin holds for g / rate.
 * Every gap is reduced by SLACK (1e-9 m) for the rounding of the double-precision
 * computations (forward kinematics and the polynomial sine and cosine stay within
 * 1e-12 m of the scalar kernels', tests/envs/models/filter/test_lanes.py).
 *
 * Precision: frames and the bounding spheres in double; the covers' and contact points'
 * distances, most of a call's work, in single precision (twice the lanes a SIMD
 * instruction), from the slot and cover centres rounded once when placed. Each such
 * distance is off by at most ROUNDING * (|a|inf + |b|inf + 2 r_a + r_b) (|x|inf: the
 * largest coordinate of a slot's centre in this lane; r: a slot's bounding radius; for
 * an unbounded b, a plane's none, another's inner shape's largest size), a bound derived
 * in docs/models.md ("Single precision"), and every comparison that proves something
 * gives that much away.
 *
 * Layout: structure of arrays, the 16 lanes innermost and contiguous, so that every
 * inner loop is one run of SIMD instructions; no per-model code.
 */
#include <math.h>
#include <stdint.h>

#define L 16
#define SLACK 1e-9
/* 128 units in the last place of single precision (2^-24 each): the error bound of a
 * single-precision distance per metre of its coordinates (docs/models.md). */
#define ROUNDING (128.0 * 0x1p-24)
enum { SPHERE, CAPSULE, BOX, CYLINDER, PLANE, UNBOUNDED };
#define NO_INNER (-1)
#define CONTACT (-2.0)
enum { FIXED_SPHERE, FIXED_HALF_SPACE, MOVING_PARTNER, OUT_OF_REACH };
#define SLIDE 2
/* Branch-free minimum and maximum (vminpd, vmaxpd: no NaN reaches them). */
#define MIN(a, b) ((a) < (b) ? (a) : (b))
#define MAX(a, b) ((a) > (b) ? (a) : (b))

/* One scene of a compiled filter (layout.CompiledScene, its row of the per-scene
 * arrays) and the covers of its moving geoms; built by lanes.py. */
typedef struct {
  int64_t nbody, nslot, npair;
  const int64_t *body_parent; const double *body_pos, *body_rot;
  const int64_t *body_jntadr, *body_jntnum, *body_flags, *jnt_type, *jnt_qposadr;
  const double *jnt_pos, *jnt_axis, *qpos0, *body_xpos, *body_xmat;
  const int64_t *slot_body; const uint8_t *slot_static; const double *slot_pos, *slot_rot;
  const int64_t *slot_type; const double *slot_size;
  const int64_t *pair_a, *pair_b; const double *pair_margin, *pair_reach;
  const int64_t *pair_kind; const double *pair_fixed;
  const int64_t *cover_start; const double *cover_pos, *cover_radius;
  const uint8_t *slot_turned;
  const int64_t *slot_inner; const double *slot_inner_size, *pair_contact;
  const uint8_t *pair_skewer;
  const int64_t *witness_start; const double *witness_offset, *witness_spacing;
  const double *slot_radius;
} Scene;

/* One call's lanes: start[nq][L], change[nq][L], t[L], cap[L], rates[npair][L] in;
 * step[L] out; work: body frames and slot centres (double), then the slot centres, slot
 * frames and cover centres in single precision (lanes.py: work_size); width: lanes
 * 0 .. width - 1 are bounded (rounded up to a multiple of 4), the rest left. */
typedef struct {
  const double *start, *change, *t, *cap, *rates;
  double *step, *work;
  int64_t width;
} Block;

/* fdlibm's reduction by pi/2 and its sine and cosine kernels on [-pi/4, pi/4] (within an
 * ulp), branch-free so that the lanes vectorise. */
static const double PIO2_1 = 1.57079632673412561417e+00, PIO2_1T = 6.07710050650619224932e-11;
static const double S1 = -1.66666666666666324348e-01, S2 = 8.33333333332248946124e-03,
                    S3 = -1.98412698298579493134e-04, S4 = 2.75573137070700676789e-06,
                    S5 = -2.50507602534068634195e-08, S6 = 1.58969099521155010221e-10;
static const double C1 = 4.16666666666666019037e-02, C2 = -1.38888888888741095749e-03,
                    C3 = 2.48015872894767294178e-05, C4 = -2.75573143513906633035e-07,
                    C5 = 2.08757232129817482790e-09, C6 = -1.13596475577881948265e-11;

static void sin_cos(int W, const double *restrict x, double *restrict sine, double *restrict cosine) {
  for (int l = 0; l < W; l++) {
    double k = floor(x[l] * 0.63661977236758134308 + 0.5);
    double r = (x[l] - k * PIO2_1) - k * PIO2_1T, z = r * r;
    double s = r + r * z * (S1 + z * (S2 + z * (S3 + z * (S4 + z * (S5 + z * S6)))));
    double c = 1.0 - 0.5 * z + z * z * (C1 + z * (C2 + z * (C3 + z * (C4 + z * (C5 + z * C6)))));
    int64_t q = (int64_t)k;
    double odd_s = (q & 1) ? c : s, odd_c = (q & 1) ? s : c;
    sine[l] = (q & 2) ? -odd_s : odd_s;
    cosine[l] = ((q + 1) & 2) ? -odd_c : odd_c;
  }
}

/* Frames of the moving bodies for every lane, composed as the scalar kernels (and
 * mj_kinematics) do: the parent's frame times the body offset, then each joint. */
static void forward(int W, const Scene *S, const Block *B, double *restrict xl, double *restrict ml) {
  double angle[L], sine[L], cosine[L];
  const double *restrict t = B->t;
  for (int64_t b = 0; b < S->nbody; b++) {
    double *restrict X = xl + b * 3 * L, *restrict M = ml + b * 9 * L;
    if (S->body_flags[b] & 1) {  /* static: its frame from the model */
      for (int i = 0; i < 3; i++)
        for (int l = 0; l < W; l++) X[i * L + l] = S->body_xpos[3 * b + i];
      for (int i = 0; i < 9; i++)
        for (int l = 0; l < W; l++) M[i * L + l] = S->body_xmat[9 * b + i];
      continue;
    }
    const double *restrict PX = xl + S->body_parent[b] * 3 * L;
    const double *restrict PM = ml + S->body_parent[b] * 9 * L;
    const double *p = S->body_pos + 3 * b, *r = S->body_rot + 9 * b;
    for (int i = 0; i < 3; i++)
      for (int l = 0; l < W; l++)
        X[i * L + l] = PX[i * L + l] + PM[3 * i * L + l] * p[0] + PM[(3 * i + 1) * L + l] * p[1]
                       + PM[(3 * i + 2) * L + l] * p[2];
    for (int i = 0; i < 3; i++)
      for (int k = 0; k < 3; k++)
        for (int l = 0; l < W; l++)
          M[(3 * i + k) * L + l] = PM[3 * i * L + l] * r[k] + PM[(3 * i + 1) * L + l] * r[3 + k]
                                   + PM[(3 * i + 2) * L + l] * r[6 + k];
    for (int64_t j = S->body_jntadr[b]; j < S->body_jntadr[b] + S->body_jntnum[b]; j++) {
      int64_t adr = S->jnt_qposadr[j];
      const double *restrict start = B->start + adr * L, *restrict change = B->change + adr * L;
      double zero = S->qpos0[adr];
      for (int l = 0; l < W; l++) angle[l] = (start[l] + t[l] * change[l]) - zero;
      const double *u = S->jnt_axis + 3 * j, *a = S->jnt_pos + 3 * j;
      if (S->jnt_type[j] == SLIDE) {
        for (int i = 0; i < 3; i++)
          for (int l = 0; l < W; l++)
            X[i * L + l] += angle[l] * (M[3 * i * L + l] * u[0] + M[(3 * i + 1) * L + l] * u[1]
                                        + M[(3 * i + 2) * L + l] * u[2]);
        continue;
      }
      sin_cos(W, angle, sine, cosine);
      double ux = u[0], uy = u[1], uz = u[2];
      for (int l = 0; l < W; l++) {  /* a turn about the hinge's anchor (Rodrigues) */
        double c = cosine[l], s = sine[l], v = 1.0 - c;
        double r00 = c + v * ux * ux, r01 = v * ux * uy - s * uz, r02 = v * ux * uz + s * uy;
        double r10 = v * ux * uy + s * uz, r11 = c + v * uy * uy, r12 = v * uy * uz - s * ux;
        double r20 = v * ux * uz - s * uy, r21 = v * uy * uz + s * ux, r22 = c + v * uz * uz;
        for (int i = 0; i < 3; i++) {
          double m0 = M[3 * i * L + l], m1 = M[(3 * i + 1) * L + l], m2 = M[(3 * i + 2) * L + l];
          double anchor = X[i * L + l] + m0 * a[0] + m1 * a[1] + m2 * a[2];
          double n0 = m0 * r00 + m1 * r10 + m2 * r20, n1 = m0 * r01 + m1 * r11 + m2 * r21,
                 n2 = m0 * r02 + m1 * r12 + m2 * r22;
          M[3 * i * L + l] = n0;
          M[(3 * i + 1) * L + l] = n1;
          M[(3 * i + 2) * L + l] = n2;
          X[i * L + l] = anchor - (n0 * a[0] + n1 * a[1] + n2 * a[2]);
        }
      }
    }
  }
}

/* Centres of the moving slots (double, and rounded to single precision), frames of those
 * that are some pair's moving partner and the cover spheres' centres (single). */
static void place(int W, const Scene *S, const double *restrict xl, const double *restrict ml,
                  double *restrict wl, float *restrict wf, float *restrict rf,
                  float *restrict cf) {
  for (int64_t s = 0; s < S->nslot; s++) {
    if (S->slot_static[s]) continue;
    int64_t b = S->slot_body[s];
    const double *restrict X = xl + b * 3 * L, *restrict M = ml + b * 9 * L;
    const double *p = S->slot_pos + 3 * s, *q = S->slot_rot + 9 * s;
    double *restrict Y = wl + s * 3 * L;
    float *restrict YF = wf + s * 3 * L, *restrict R = rf + s * 9 * L;
    for (int i = 0; i < 3; i++)
      for (int l = 0; l < W; l++) {
        double y = X[i * L + l] + M[3 * i * L + l] * p[0] + M[(3 * i + 1) * L + l] * p[1]
                   + M[(3 * i + 2) * L + l] * p[2];
        Y[i * L + l] = y;
        YF[i * L + l] = (float)y;
      }
    if (S->slot_turned[s])
      for (int i = 0; i < 3; i++)
        for (int k = 0; k < 3; k++)
          for (int l = 0; l < W; l++)
            R[(3 * i + k) * L + l] = (float)(M[3 * i * L + l] * q[k]
                                             + M[(3 * i + 1) * L + l] * q[3 + k]
                                             + M[(3 * i + 2) * L + l] * q[6 + k]);
    for (int64_t c = S->cover_start[s]; c < S->cover_start[s + 1]; c++) {
      const double *o = S->cover_pos + 3 * c;
      float *restrict C = cf + c * 3 * L;
      for (int i = 0; i < 3; i++)
        for (int l = 0; l < W; l++)
          C[i * L + l] = (float)(X[i * L + l] + M[3 * i * L + l] * o[0]
                                 + M[(3 * i + 1) * L + l] * o[1] + M[(3 * i + 2) * L + l] * o[2]);
    }
  }
}

/* (lx, ly, lz)[l] = the points (px, py, pz)[l] in slot b's frame (static: the scene's;
 * moving: each lane's), in single precision. */
static inline void in_frame(int W, const Scene *S, int64_t b, const float *restrict px,
                            const float *restrict py, const float *restrict pz,
                            const float *restrict wf, const float *restrict rf,
                            float *restrict lx, float *restrict ly, float *restrict lz) {
  if (S->slot_static[b]) {
    float o[3], q[9];
    for (int i = 0; i < 3; i++) o[i] = (float)S->slot_pos[3 * b + i];
    for (int i = 0; i < 9; i++) q[i] = (float)S->slot_rot[9 * b + i];
    for (int l = 0; l < W; l++) {
      float dx = px[l] - o[0], dy = py[l] - o[1], dz = pz[l] - o[2];
      lx[l] = q[0] * dx + q[3] * dy + q[6] * dz;
      ly[l] = q[1] * dx + q[4] * dy + q[7] * dz;
      lz[l] = q[2] * dx + q[5] * dy + q[8] * dz;
    }
    return;
  }
  const float *restrict WB = wf + b * 3 * L, *restrict R = rf + b * 9 * L;
  for (int l = 0; l < W; l++) {
    float dx = px[l] - WB[l], dy = py[l] - WB[L + l], dz = pz[l] - WB[2 * L + l];
    lx[l] = R[l] * dx + R[3 * L + l] * dy + R[6 * L + l] * dz;
    ly[l] = R[L + l] * dx + R[4 * L + l] * dy + R[7 * L + l] * dz;
    lz[l] = R[2 * L + l] * dx + R[5 * L + l] * dy + R[8 * L + l] * dz;
  }
}

/* fine[l] = min over a's cover spheres of (distance of the centre to b's container) less
 * the sphere's radius, in b's frame (static: the scene's; moving: each lane's), for b of
 * one kind and frame (compile-time constants where cover_gaps calls it): each lane's
 * centre goes into b's frame and to its distance in one loop, whose values stay in
 * registers instead of passing through arrays on the stack (docs/models.md). Single
 * precision: off by at most the call's rounding bound (lane_block). */
static inline void cover_gaps_of(int W, const Scene *S, int64_t a, int64_t b, const int fixed,
                                 const int64_t kind, const float *restrict wf,
                                 const float *restrict rf, const float *restrict cf,
                                 float *restrict fine) {
  const double *size = S->slot_size + 3 * b;
  float s0 = (float)size[0], s1 = (float)size[1], s2 = (float)size[2];
  float o[3], q[9];
  for (int i = 0; i < 3; i++) o[i] = (float)S->slot_pos[3 * b + i];
  for (int i = 0; i < 9; i++) q[i] = (float)S->slot_rot[9 * b + i];
  const float *restrict WB = wf + b * 3 * L, *restrict R = rf + b * 9 * L;
  for (int l = 0; l < W; l++) fine[l] = INFINITY;
  for (int64_t c = S->cover_start[a]; c < S->cover_start[a + 1]; c++) {
    const float *restrict C = cf + c * 3 * L;
    float radius = (float)S->cover_radius[c];
    for (int l = 0; l < W; l++) {
      /* the centre in b's frame, as in_frame computes it */
      float dx = C[l] - (fixed ? o[0] : WB[l]), dy = C[L + l] - (fixed ? o[1] : WB[L + l]),
            dz = C[2 * L + l] - (fixed ? o[2] : WB[2 * L + l]);
      float lx = (fixed ? q[0] : R[l]) * dx + (fixed ? q[3] : R[3 * L + l]) * dy
                 + (fixed ? q[6] : R[6 * L + l]) * dz;
      float ly = (fixed ? q[1] : R[L + l]) * dx + (fixed ? q[4] : R[4 * L + l]) * dy
                 + (fixed ? q[7] : R[7 * L + l]) * dz;
      float lz = (fixed ? q[2] : R[2 * L + l]) * dx + (fixed ? q[5] : R[5 * L + l]) * dy
                 + (fixed ? q[8] : R[8 * L + l]) * dz;
      float gap;
      if (kind == SPHERE) {
        gap = sqrtf(lx * lx + ly * ly + lz * lz) - s0 - radius;
      } else if (kind == CAPSULE) {
        float z = lz - MIN(MAX(lz, -s1), s1);
        gap = sqrtf(lx * lx + ly * ly + z * z) - s0 - radius;
      } else if (kind == BOX) {
        float ex = MAX(fabsf(lx) - s0, 0.0f), ey = MAX(fabsf(ly) - s1, 0.0f),
              ez = MAX(fabsf(lz) - s2, 0.0f);
        gap = sqrtf(ex * ex + ey * ey + ez * ez) - radius;
      } else if (kind == CYLINDER) {
        float er = MAX(sqrtf(lx * lx + ly * ly) - s0, 0.0f), ez = MAX(fabsf(lz) - s1, 0.0f);
        gap = sqrtf(er * er + ez * ez) - radius;
      } else { /* PLANE: the half-space below its z = 0 */
        gap = lz - radius;
      }
      fine[l] = MIN(fine[l], gap);
    }
  }
}

/* cover_gaps_of, its kind and frame made constants: one specialised loop each. */
static void cover_gaps(int W, const Scene *S, int64_t a, int64_t b, const float *restrict wf,
                       const float *restrict rf, const float *restrict cf,
                       float *restrict fine) {
#define COVER_GAPS(fixed, kind) cover_gaps_of(W, S, a, b, fixed, kind, wf, rf, cf, fine); break
  int64_t kind = S->slot_type[b];
  if (S->slot_static[b]) {
    switch (kind) {
    case SPHERE: COVER_GAPS(1, SPHERE);
    case CAPSULE: COVER_GAPS(1, CAPSULE);
    case BOX: COVER_GAPS(1, BOX);
    case CYLINDER: COVER_GAPS(1, CYLINDER);
    default: COVER_GAPS(1, PLANE);
    }
  } else {
    switch (kind) {
    case SPHERE: COVER_GAPS(0, SPHERE);
    case CAPSULE: COVER_GAPS(0, CAPSULE);
    case BOX: COVER_GAPS(0, BOX);
    case CYLINDER: COVER_GAPS(0, CYLINDER);
    default: COVER_GAPS(0, PLANE);
    }
  }
#undef COVER_GAPS
}

/* contact[l] |= the inner shapes of pair k (a moving, with witness points) are closer than
 * the pair's contact distance, by the points (layout.inner, lanes.py: witness_points):
 * each point p of a's inner segment (its sphere: the centre) with a's inner radius r is a
 * ball inside a, so the signed distance of p to b's inner shape less r bounds the pair's
 * from above (a box's point distance is 0 inside it, above its signed one). A capsule
 * and a primitive box (pair_skewer) also need what MuJoCo's collider sees: not its axis
 * through the box with both ends outside. Proven where every point is farther than half
 * their spacing from the box (the axis then misses it: the point distance changes at
 * most as fast as the point moves) or an end lies inside the box by SLACK. The distances
 * in single precision, each comparison giving away rounding[l] (lane_block). */
static void witness(int W, const Scene *S, int64_t k, int64_t a, int64_t b,
                    const double *restrict ml, const float *restrict wf,
                    const float *restrict rf, const double *restrict rounding,
                    double *restrict contact) {
  float px[L], py[L], pz[L], lx[L], ly[L], lz[L], ux[L], uy[L], uz[L], best[L], inside[L];
  const double *ib = S->slot_inner_size + 3 * b;
  float b0 = (float)ib[0], b1 = (float)ib[1], b2 = (float)ib[2];
  int64_t kind = S->slot_inner[b];
  int skewer = S->pair_skewer[k] != 0;
  double radius = S->slot_inner_size[3 * a], limit = S->pair_contact[k];
  double spacing = S->witness_spacing[a];
  const float *restrict X = wf + a * 3 * L;
  const double *restrict M = ml + S->slot_body[a] * 9 * L;
  const double *q = S->slot_rot + 9 * a;
  for (int i = 0; i < 3; i++) {  /* a's axis in the world */
    float *restrict u = i == 0 ? ux : (i == 1 ? uy : uz);
    for (int l = 0; l < W; l++)
      u[l] = (float)(M[3 * i * L + l] * q[2] + M[(3 * i + 1) * L + l] * q[5]
                     + M[(3 * i + 2) * L + l] * q[8]);
  }
  /* an end inside the box by SLACK, with the rounding given away */
  float deep[L];
  for (int l = 0; l < W; l++)
    best[l] = INFINITY, inside[l] = 0.0f, deep[l] = (float)(SLACK + rounding[l]);
  int64_t first = S->witness_start[a], last = S->witness_start[a + 1] - 1;
  for (int64_t c = first; c <= last; c++) {
    float z = (float)S->witness_offset[c];
    for (int l = 0; l < W; l++)
      px[l] = X[l] + ux[l] * z, py[l] = X[L + l] + uy[l] * z, pz[l] = X[2 * L + l] + uz[l] * z;
    in_frame(W, S, b, px, py, pz, wf, rf, lx, ly, lz);
    switch (kind) {
    case SPHERE:
      for (int l = 0; l < W; l++)
        best[l] = MIN(best[l], sqrtf(lx[l] * lx[l] + ly[l] * ly[l] + lz[l] * lz[l]) - b0);
      break;
    case CAPSULE:
      for (int l = 0; l < W; l++) {
        float h = lz[l] - MIN(MAX(lz[l], -b1), b1);
        best[l] = MIN(best[l], sqrtf(lx[l] * lx[l] + ly[l] * ly[l] + h * h) - b0);
      }
      break;
    case BOX: {
      int end = c == first || c == last;
      for (int l = 0; l < W; l++) {
        float ax = fabsf(lx[l]), ay = fabsf(ly[l]), az = fabsf(lz[l]);
        float ex = MAX(ax - b0, 0.0f), ey = MAX(ay - b1, 0.0f), ez = MAX(az - b2, 0.0f);
        best[l] = MIN(best[l], sqrtf(ex * ex + ey * ey + ez * ez));
        float in = (ax + deep[l] <= b0) & (ay + deep[l] <= b1) & (az + deep[l] <= b2);
        inside[l] = end ? MAX(inside[l], in) : inside[l];
      }
      break;
    }
    default: /* PLANE: the half-space below its z = 0 */
      for (int l = 0; l < W; l++) best[l] = MIN(best[l], lz[l]);
    }
  }
  for (int l = 0; l < W; l++) {
    double least = (double)best[l];
    double near = (least + rounding[l] - radius + SLACK < limit);
    double clear = skewer ? (least - rounding[l] > 0.5 * spacing + SLACK) : 1.0;
    contact[l] = MAX(contact[l], MAX(near * clear, skewer ? (double)inside[l] : 0.0));
  }
}

/* The largest coordinate of slot s's centre in each lane (static: the scene's). */
static inline void extent(int W, const Scene *S, int64_t s, const double *restrict wl,
                          double *restrict out) {
  if (S->slot_static[s]) {
    const double *o = S->slot_pos + 3 * s;
    double m = MAX(MAX(fabs(o[0]), fabs(o[1])), fabs(o[2]));
    for (int l = 0; l < W; l++) out[l] = m;
    return;
  }
  const double *restrict Y = wl + s * 3 * L;
  for (int l = 0; l < W; l++)
    out[l] = MAX(MAX(fabs(Y[l]), fabs(Y[L + l])), fabs(Y[2 * L + l]));
}

void lane_block(const Scene *S, Block *B) {
  double gap[L], contact[L], rounding[L], ea[L], eb[L];
  float fine[L];
  double *steps = B->step;
  double *xl = B->work, *ml = xl + S->nbody * 3 * L, *wl = ml + S->nbody * 9 * L;
  float *wf = (float *)(wl + S->nslot * 3 * L), *rf = wf + S->nslot * 3 * L;
  float *cf = rf + S->nslot * 9 * L;
  int W = (int)((B->width + 3) & ~(int64_t)3);
  if (W > L) W = L;
  forward(W, S, B, xl, ml);
  place(W, S, xl, ml, wl, wf, rf, cf);
  for (int l = 0; l < W; l++) steps[l] = B->cap[l], contact[l] = 0.0;
  for (int64_t k = 0; k < S->npair; k++) {
    int64_t kind = S->pair_kind[k];
    if (kind == OUT_OF_REACH) continue;
    int64_t a = S->pair_a[k], b = S->pair_b[k];
    const double *restrict rate = B->rates + k * L, *f = S->pair_fixed + 6 * k;
    const double *restrict WA = wl + a * 3 * L, *restrict WB = wl + b * 3 * L;
    double reach = S->pair_reach[k];
    /* The bounding spheres (a half-space for a plane) first, in double precision. */
    if (kind == FIXED_HALF_SPACE) {
      for (int l = 0; l < W; l++)
        gap[l] = f[3] * (WA[l] - f[0]) + f[4] * (WA[L + l] - f[1]) + f[5] * (WA[2 * L + l] - f[2])
                 - reach;
    } else {
      for (int l = 0; l < W; l++) {
        double dx = WA[l] - (kind == FIXED_SPHERE ? f[0] : WB[l]);
        double dy = WA[L + l] - (kind == FIXED_SPHERE ? f[1] : WB[L + l]);
        double dz = WA[2 * L + l] - (kind == FIXED_SPHERE ? f[2] : WB[2 * L + l]);
        gap[l] = sqrt(dx * dx + dy * dy + dz * dz) - reach;
      }
    }
    int far = 1;
    for (int l = 0; l < W; l++) far &= gap[l] - SLACK >= rate[l] * steps[l];
    if (far) continue;
    /* What the single-precision distances of this pair may be off by, per lane. */
    double ra = S->slot_radius[a], rb = S->slot_radius[b], radii = 2.0 * ra;
    if (isfinite(rb)) {
      radii += rb;  /* every size of b's container and inner shape is at most rb */
    } else if (S->slot_inner[b] == SPHERE || S->slot_inner[b] == CAPSULE || S->slot_inner[b] == BOX) {
      /* An unbounded b is a half-space (no size) or has no inner shape today; should one
       * get a sized inner shape, its sizes count. */
      const double *ib = S->slot_inner_size + 3 * b;
      radii += MAX(MAX(fabs(ib[0]), fabs(ib[1])), fabs(ib[2]));
    }
    extent(W, S, a, wl, ea);
    extent(W, S, b, wl, eb);
    for (int l = 0; l < W; l++) rounding[l] = ROUNDING * (ea[l] + eb[l] + radii);
    if (S->cover_start[a] == S->cover_start[a + 1] || S->slot_type[b] == UNBOUNDED) {
      for (int l = 0; l < W; l++) fine[l] = -INFINITY;
    } else {
      cover_gaps(W, S, a, b, wf, rf, cf, fine);
    }
    double margin = S->pair_margin[k];
    int open = 0;
    for (int l = 0; l < W; l++) {
      double g = MAX(gap[l], ((double)fine[l] - rounding[l]) - margin) - SLACK;
      double step = rate[l] > 0.0 ? g / rate[l] : INFINITY;
      steps[l] = MIN(steps[l], g > 0.0 ? step : -1.0);
      open |= g <= 0.0;
    }
    if (open && S->witness_start[a] < S->witness_start[a + 1] && S->slot_inner[b] != NO_INNER
        && S->pair_contact[k] > -INFINITY) {
      witness(W, S, k, a, b, ml, wf, rf, rounding, contact);
      int decided = 1;
      for (int l = 0; l < W; l++) decided &= contact[l] > 0.0;
      if (decided) break;  /* every lane in contact: the other pairs cannot change that */
    }
  }
  for (int l = 0; l < W; l++) steps[l] = contact[l] > 0.0 ? CONTACT : steps[l];
}
