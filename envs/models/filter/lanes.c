/* Lanes: 16 samples at once, for the collision filter's path and configuration checks.
 *
 * Each lane holds one sample of a linear joint path (its own path: start, change, path
 * parameter t, per-pair rates; a configuration is a path that does not move) and gets a
 * step s >= 0 such that every candidate pair of the scene stays farther than its contact
 * margin for |t' - t| <= s along that path, from lower bounds only; or CONTACT (-2) where
 * a witness proves a pair in contact (witness below); or -1 where neither is proven (the
 * caller then decides that sample exactly). s never exceeds the lane's cap.
 *
 * The bounds: each moving geom's container is held by spheres (on a capsule's or
 * cylinder's axis, a sphere itself, about the cells of a box: "covers", lanes.py); the
 * distance of a cover sphere's centre to the partner's container (a point to a sphere,
 * capsule, box, cylinder or half-space, in closed form) less its radius bounds the pair's
 * distance from below, and so does the gap of the two bounding spheres; a geom's height
 * over a half-space less its extent along the normal is its distance (plane_gaps), and a
 * moving box's separation along a face normal bounds its distance too (box_gaps). A pair
 * closes at most at its rate (m per unit t, as the scalar kernels use it), so a gap g
 * beyond the margin holds for g / rate.
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
#include <stddef.h>
#include <stdint.h>

#define L 16
#define SLACK 1e-9
#define FAR_SQUARED 1e-12
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
/* Inlined into lane_block, so that a full block's loops run over the constant L. */
#define INLINE static inline __attribute__((always_inline))

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
  /* a pair of two primitive boxes: MuJoCo's collider reports some contacts outside the
   * margin (docs/models.md, "Witnesses"), so only the bounding spheres, the test MuJoCo's
   * own broad phase makes, prove it free */
  const uint8_t *pair_spheres;
} Scene;

/* One call's lanes: start[nq][L], change[nq][L], t[L], cap[L], rates[npair][L] in;
 * step[L] out; work: body frames, slot centres and their largest coordinates (double),
 * then the slot centres, slot frames and cover centres in single precision (lanes.py:
 * work_size); width: lanes 0 .. width - 1 are bounded (rounded up to a multiple of 4),
 * the rest left. */
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

INLINE void sin_cos(int W, const double *restrict x, double *restrict sine, double *restrict cosine) {
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
 * mj_kinematics) do: the parent's frame times the body offset, then each joint. A static
 * body's frame is the model's, laid into the lanes only where a moving child needs it
 * (nothing else reads them: static slots are placed in the world). */
INLINE void forward(int W, const Scene *S, const Block *B, double *restrict xl, double *restrict ml) {
  double angle[L], sine[L], cosine[L];
  const double *restrict t = B->t;
  for (int64_t b = 0; b < S->nbody; b++) {
    if (S->body_flags[b] & 1) continue;
    double *restrict X = xl + b * 3 * L, *restrict M = ml + b * 9 * L;
    int64_t parent = S->body_parent[b];
    double *restrict PX = xl + parent * 3 * L, *restrict PM = ml + parent * 9 * L;
    if (S->body_flags[parent] & 1) {
      for (int i = 0; i < 3; i++)
        for (int l = 0; l < W; l++) PX[i * L + l] = S->body_xpos[3 * parent + i];
      for (int i = 0; i < 9; i++)
        for (int l = 0; l < W; l++) PM[i * L + l] = S->body_xmat[9 * parent + i];
    }
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

/* Centres of the moving slots (double, and rounded to single precision) and their largest
 * coordinates, frames of those that are some pair's moving partner and the cover spheres'
 * centres (single). */
INLINE void place(int W, const Scene *S, const double *restrict xl, const double *restrict ml,
                  double *restrict wl, double *restrict el, float *restrict wf,
                  float *restrict rf, float *restrict cf) {
  for (int64_t s = 0; s < S->nslot; s++) {
    if (S->slot_static[s]) continue;
    int64_t b = S->slot_body[s];
    const double *restrict X = xl + b * 3 * L, *restrict M = ml + b * 9 * L;
    const double *p = S->slot_pos + 3 * s, *q = S->slot_rot + 9 * s;
    double *restrict Y = wl + s * 3 * L, *restrict E = el + s * L;
    float *restrict YF = wf + s * 3 * L, *restrict R = rf + s * 9 * L;
    for (int i = 0; i < 3; i++)
      for (int l = 0; l < W; l++) {
        double y = X[i * L + l] + M[3 * i * L + l] * p[0] + M[(3 * i + 1) * L + l] * p[1]
                   + M[(3 * i + 2) * L + l] * p[2];
        Y[i * L + l] = y;
        YF[i * L + l] = (float)y;
      }
    for (int l = 0; l < W; l++) E[l] = MAX(MAX(fabs(Y[l]), fabs(Y[L + l])), fabs(Y[2 * L + l]));
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
INLINE void in_frame(int W, const Scene *S, int64_t b, const float *restrict px,
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
INLINE void cover_gaps_of(int W, const Scene *S, int64_t a, int64_t b, const int fixed,
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
INLINE void cover_gaps(int W, const Scene *S, int64_t a, int64_t b, const float *restrict wf,
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

/* axes[(3 k + i) L + l] = component i of slot s's axis k in the world (column k of its
 * body's frame times the slot's rotation), in double precision. */
INLINE void slot_axes(int W, const Scene *S, int64_t s, const double *restrict ml,
                      double *restrict axes) {
  const double *q = S->slot_rot + 9 * s;
  if (S->slot_static[s]) {
    for (int k = 0; k < 3; k++)
      for (int i = 0; i < 3; i++)
        for (int l = 0; l < W; l++) axes[(3 * k + i) * L + l] = q[3 * i + k];
    return;
  }
  const double *restrict M = ml + S->slot_body[s] * 9 * L;
  for (int k = 0; k < 3; k++)
    for (int i = 0; i < 3; i++)
      for (int l = 0; l < W; l++)
        axes[(3 * k + i) * L + l] = M[3 * i * L + l] * q[k] + M[(3 * i + 1) * L + l] * q[3 + k]
                                    + M[(3 * i + 2) * L + l] * q[6 + k];
}

/* e[l] = the extent of slot a's container about its centre along the unit axis
 * (nx, ny, nz)[l], from a's axes ua (slot_axes): a box's sum_j h_j |n . u_j|, a
 * sphere's r, a capsule's r + h |n . z|, a cylinder's r sqrt(1 - (n . z)^2) + h |n . z|. */
INLINE void extent(int W, int64_t kind, const double *size, const double *restrict ua,
                   const double *restrict nx, const double *restrict ny,
                   const double *restrict nz, double *restrict e) {
  for (int l = 0; l < W; l++) {
    if (kind == BOX) {
      double sum = 0.0;
      for (int j = 0; j < 3; j++)
        sum += size[j] * fabs(nx[l] * ua[3 * j * L + l] + ny[l] * ua[(3 * j + 1) * L + l]
                              + nz[l] * ua[(3 * j + 2) * L + l]);
      e[l] = sum;
    } else if (kind == SPHERE) {
      e[l] = size[0];
    } else {
      double c = nx[l] * ua[6 * L + l] + ny[l] * ua[7 * L + l] + nz[l] * ua[8 * L + l];
      e[l] = size[1] * fabs(c)
             + (kind == CAPSULE ? size[0] : size[0] * sqrt(MAX(1.0 - c * c, 0.0)));
    }
  }
}

/* exact[l] = the signed distance of slot a's container (a box or a cylinder) to the
 * half-space f of a pair (pair_fixed: a point of its plane, then its normal; a plane
 * never moves): the height of a's centre over the plane less a's extent along the
 * normal. The covers' spheres reach past a flat cylinder's faces, which a turntable
 * holds at a constant height over the floor. In double precision, from the frames and
 * centres the lanes computed (SLACK holds their rounding, as for the bounding spheres). */
INLINE void plane_gaps(int W, const Scene *S, int64_t a, const double *f,
                       const double *restrict ml, const double *restrict wl,
                       double *restrict exact) {
  double ua[9 * L], nx[L], ny[L], nz[L], e[L];
  slot_axes(W, S, a, ml, ua);
  for (int l = 0; l < W; l++) nx[l] = f[3], ny[l] = f[4], nz[l] = f[5];
  extent(W, S->slot_type[a], S->slot_size + 3 * a, ua, nx, ny, nz, e);
  const double *restrict WA = wl + a * 3 * L;
  for (int l = 0; l < W; l++)
    exact[l] = f[3] * (WA[l] - f[0]) + f[4] * (WA[L + l] - f[1]) + f[5] * (WA[2 * L + l] - f[2])
               - e[l];
}

/* sat[l] = a lower bound of the distance between the box a (moving) and b's container (a
 * sphere, capsule, box or cylinder): the largest gap between their extents along one of
 * a's face normals, or one of b's for a box b. Along any unit axis n two convex sets lie
 * at least |n . (c_b - c_a)| - e_a(n) - e_b(n) apart (extent). Exact for faces that face
 * each other (a carriage beside its rails), where the covers' spheres reach past the
 * box. In double precision, as plane_gaps. */
INLINE void box_gaps(int W, const Scene *S, int64_t a, int64_t b, const double *restrict ml,
                     const double *restrict wl, double *restrict sat) {
  double ua[9 * L], ub[9 * L], d[3 * L], other[L];
  slot_axes(W, S, a, ml, ua);
  slot_axes(W, S, b, ml, ub);
  const double *restrict WA = wl + a * 3 * L, *restrict WB = wl + b * 3 * L;
  const double *o = S->slot_pos + 3 * b;
  int fixed = S->slot_static[b];
  for (int i = 0; i < 3; i++)
    for (int l = 0; l < W; l++) d[i * L + l] = (fixed ? o[i] : WB[i * L + l]) - WA[i * L + l];
  const double *ha = S->slot_size + 3 * a, *hb = S->slot_size + 3 * b;
  int64_t kind = S->slot_type[b];
  for (int l = 0; l < W; l++) sat[l] = -INFINITY;
  for (int side = 0; side < (kind == BOX ? 2 : 1); side++) { /* a's face normals, b's */
    const double *restrict axes = side ? ub : ua;
    const double *half = side ? hb : ha;
    for (int k = 0; k < 3; k++) {
      const double *nx = axes + 3 * k * L, *ny = nx + L, *nz = ny + L;
      /* along a face normal of a box its own extent is that half-size */
      if (side)
        extent(W, BOX, ha, ua, nx, ny, nz, other);
      else
        extent(W, kind, hb, ub, nx, ny, nz, other);
      for (int l = 0; l < W; l++) {
        double along = fabs(nx[l] * d[l] + ny[l] * d[L + l] + nz[l] * d[2 * L + l]);
        sat[l] = MAX(sat[l], along - half[k] - other[l]);
      }
    }
  }
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
INLINE void witness(int W, const Scene *S, int64_t k, int64_t a, int64_t b,
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

/* lane_block for lanes 0 .. W - 1. */
INLINE void bound_lanes(const Scene *S, Block *B, const int W) {
  double gap[L], contact[L], rounding[L];
  float fine[L];
  double *steps = B->step;
  double *xl = B->work, *ml = xl + S->nbody * 3 * L, *wl = ml + S->nbody * 9 * L;
  double *el = wl + S->nslot * 3 * L;
  float *wf = (float *)(el + S->nslot * L), *rf = wf + S->nslot * 3 * L;
  float *cf = rf + S->nslot * 9 * L;
  forward(W, S, B, xl, ml);
  place(W, S, xl, ml, wl, el, wf, rf, cf);
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
      int far = 1;
      for (int l = 0; l < W; l++) far &= gap[l] - SLACK >= rate[l] * steps[l];
      if (far) continue;
    } else {
      /* Squared distances: a lane is far where d^2 > (reach + SLACK + rate step)^2
       * (1 + FAR_SQUARED), which implies d - reach - SLACK >= rate step (FAR_SQUARED is
       * far above the rounding of either side), so only the pairs that go on take a
       * root. */
      int far = 1;
      for (int l = 0; l < W; l++) {
        double dx = WA[l] - (kind == FIXED_SPHERE ? f[0] : WB[l]);
        double dy = WA[L + l] - (kind == FIXED_SPHERE ? f[1] : WB[L + l]);
        double dz = WA[2 * L + l] - (kind == FIXED_SPHERE ? f[2] : WB[2 * L + l]);
        double t = reach + SLACK + rate[l] * steps[l];
        gap[l] = dx * dx + dy * dy + dz * dz;
        far &= (t <= 0.0) | (gap[l] > t * t * (1.0 + FAR_SQUARED));
      }
      if (far) continue;
      for (int l = 0; l < W; l++) gap[l] = sqrt(gap[l]) - reach;
    }
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
    /* a moves; a static b's largest coordinate is the scene's */
    const double *restrict EA = el + a * L, *restrict EB = el + b * L;
    if (S->slot_static[b]) {
      const double *o = S->slot_pos + 3 * b;
      double eb = MAX(MAX(fabs(o[0]), fabs(o[1])), fabs(o[2]));
      for (int l = 0; l < W; l++) rounding[l] = ROUNDING * (EA[l] + eb + radii);
    } else {
      for (int l = 0; l < W; l++) rounding[l] = ROUNDING * (EA[l] + EB[l] + radii);
    }
    double margin = S->pair_margin[k];
    int spheres = S->pair_spheres[k];
    /* a box or a cylinder over a half-space (a capsule's or a sphere's covers reach
     * below it by little or nothing, and cost less) */
    int planar = kind == FIXED_HALF_SPACE
                 && (S->slot_type[a] == BOX || S->slot_type[a] == CYLINDER);
    if (!spheres && (planar || (S->slot_type[a] == BOX && S->slot_type[b] != UNBOUNDED))) {
      /* a half-space's distance exactly, a box's separation: where that holds every
       * lane, no covers (nor any for a half-space: they cannot do better) */
      double sat[L];
      if (planar)
        plane_gaps(W, S, a, f, ml, wl, sat);
      else
        box_gaps(W, S, a, b, ml, wl, sat);
      int far = 1;
      for (int l = 0; l < W; l++) {
        gap[l] = MAX(gap[l], sat[l] - margin);
        far &= gap[l] - SLACK >= rate[l] * steps[l];
      }
      if (far) continue;
    }
    if (spheres || planar || S->cover_start[a] == S->cover_start[a + 1]
        || S->slot_type[b] == UNBOUNDED) {
      for (int l = 0; l < W; l++) fine[l] = -INFINITY;
    } else {
      cover_gaps(W, S, a, b, wf, rf, cf, fine);
    }
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

void lane_block(const Scene *S, Block *B) {
  int64_t width = (B->width + 3) & ~(int64_t)3;  /* the loops' vectors: 4 lanes at least */
  if (width >= L)
    bound_lanes(S, B, L);  /* the common case: every loop of a constant length */
  else
    bound_lanes(S, B, (int)width);
}

/* ------------------------------------------------------------------ path searches
 * The raked search of kernels._lane_paths, up to L paths in flight: each path keeps a
 * queue of grid intervals [lo, hi] and its lowest contact found; a round takes the next
 * interval of every path in turn until the lanes are full, bounds their middle samples
 * (lane_block) and goes on as the scalar loop does. A sample the lanes prove neither
 * free nor in contact is handed back: lane_paths returns PATHS_SCALAR with `lane` set,
 * the caller writes that sample's step into the block (>= 0 free, < 0 in contact) and
 * calls again, which goes on from that lane. The paths of one scene share the lanes; a
 * new scene waits until every path of the one before has finished. */
enum { PATHS_DONE = 0, PATHS_SCALAR = 1 };

/* One call's search: set by the caller (kernels._lane_paths; every field 8 bytes, in
 * this order), then the search's own state (zero to begin). */
typedef struct {
  int64_t count, nq, npair, first, size, lane_min, nscenes;
  const int64_t *steps, *scenes;     /* steps[count]; scenes[nscenes]: 1, or count */
  const uint64_t *scene_address;     /* per scene index: its Scene */
  const double *start, *change, *rates;  /* per path: [count][nq], [count][nq], [count][npair] */
  int64_t *out, *counters, *queue_lo, *queue_hi;  /* queues: [L][size] */
  Block *block;
  int64_t started, taken, current, parts, width, lane, in_round, resume;
  int64_t path[L], grid[L], found[L], head[L], tail[L];  /* the places: paths in flight */
  int64_t owner[L], loaded[L], lo[L], hi[L], mid[L];     /* the round's lanes */
} Paths;

/* The layout the caller lays Paths out by, in int64 fields: the offsets of the fields it
 * sets (count ... block) and reads (current, lane, path, owner, lo, hi, mid), the
 * struct's size and PATHS_SCALAR; lanes.py checks them against its own. */
void lane_paths_layout(int64_t *out) {
#define AT(field) (int64_t)(offsetof(Paths, field) / sizeof(int64_t))
  const int64_t layout[] = {
      AT(count), AT(nq), AT(npair), AT(first), AT(size), AT(lane_min), AT(nscenes), AT(steps),
      AT(scenes), AT(scene_address), AT(start), AT(change), AT(rates), AT(out), AT(counters),
      AT(queue_lo), AT(queue_hi), AT(block), AT(current), AT(lane), AT(path), AT(owner),
      AT(lo), AT(hi), AT(mid), (int64_t)(sizeof(Paths) / sizeof(int64_t)), PATHS_SCALAR};
#undef AT
  for (int i = 0; i < (int)(sizeof(layout) / sizeof(layout[0])); i++) out[i] = layout[i];
}

static inline int64_t path_scene(const Paths *P, int64_t m) {
  return P->nscenes == 1 ? P->scenes[0] : P->scenes[m];
}

static inline int64_t push_interval(const Paths *P, int64_t p, int64_t tail, int64_t lo,
                                    int64_t hi) {
  if (lo <= hi) {
    P->queue_lo[p * P->size + tail] = lo, P->queue_hi[p * P->size + tail] = hi;
    tail = (tail + 1) % P->size;
  }
  return tail;
}

/* Write out the paths whose queues are empty; give their places to the next paths of the
 * scene in flight (current; -1: any, whose paths then set the first intervals of each:
 * as many as that scene's own filter would start them from). */
static void take_paths(Paths *P) {
  for (int p = 0; p < L; p++) {
    if (P->path[p] >= 0 && P->head[p] == P->tail[p]) {
      P->out[P->path[p]] = P->found[p] <= P->grid[p] ? P->found[p] : -1;
      P->path[p] = -1;
    }
    if (P->path[p] >= 0 || P->taken == P->count) continue;
    int64_t e = path_scene(P, P->taken);
    if (P->current >= 0 && e != P->current) continue;
    if (P->current < 0) {
      int64_t run = P->count - P->taken;
      if (P->nscenes != 1) {
        run = 1;
        while (P->taken + run < P->count && P->scenes[P->taken + run] == e) run++;
      }
      P->parts = MAX(1, L / MIN(run, L));
    }
    P->current = e;
    int64_t m = P->taken++, n = P->steps[m];
    P->path[p] = m, P->grid[p] = n, P->found[p] = n + 1;
    int64_t split = MIN(P->parts, n + 1);
    P->head[p] = 0, P->tail[p] = split;
    for (int64_t i = 0; i < split; i++) {
      P->queue_lo[p * P->size + i] = (i * (n + 1)) / split;
      P->queue_hi[p * P->size + i] = ((i + 1) * (n + 1)) / split - 1;
    }
  }
}

/* Pop path p's next interval that still holds grid indices below its contact into lane. */
static inline int next_interval(Paths *P, int64_t p, int lane) {
  const int64_t *qlo = P->queue_lo + p * P->size, *qhi = P->queue_hi + p * P->size;
  while (P->head[p] != P->tail[p]) {
    int64_t a = qlo[P->head[p]], b = qhi[P->head[p]];
    P->head[p] = (P->head[p] + 1) % P->size;
    if (b >= P->found[p]) b = P->found[p] - 1;
    if (a <= b) {
      P->lo[lane] = a, P->hi[lane] = b;
      return 1;
    }
  }
  return 0;
}

/* A round's intervals: every path's next one in turn until the lanes are full. */
static int gather(Paths *P) {
  int width = 0, more = 1;
  while (more && width < L) {
    more = 0;
    for (int p = 0; p < L; p++) {
      if (width == L) break;
      if (P->path[p] < 0 || !next_interval(P, p, width)) continue;
      P->owner[width] = p, P->mid[width] = (P->lo[width] + P->hi[width]) / 2;
      width++;
      more = 1;
    }
  }
  return width;
}

/* Load the round's samples into the block (a lane's start, change and rates only when its
 * path changed) and bound them; with fewer than lane_min they are left undecided. */
static void bound_round(Paths *P, int width) {
  Block *B = P->block;
  double *step = B->step;
  if (width < P->lane_min) {
    for (int l = 0; l < width; l++) step[l] = -1.0;
    return;
  }
  double *start = (double *)B->start, *change = (double *)B->change, *t = (double *)B->t;
  double *cap = (double *)B->cap, *rates = (double *)B->rates;
  for (int l = 0; l < width; l++) {
    int64_t p = P->owner[l], m = P->path[p];
    if (P->loaded[l] != m) {
      P->loaded[l] = m;
      for (int64_t j = 0; j < P->nq; j++)
        start[j * L + l] = P->start[m * P->nq + j], change[j * L + l] = P->change[m * P->nq + j];
      for (int64_t k = 0; k < P->npair; k++) rates[k * L + l] = P->rates[m * P->npair + k];
    }
    double n = (double)P->grid[p];
    t[l] = (double)P->mid[l] / n;
    cap[l] = (double)MAX(P->mid[l] - P->lo[l], P->hi[l] - P->mid[l]) / n;
  }
  B->width = width;
  lane_block((const Scene *)(uintptr_t)P->scene_address[P->current], B);
  P->counters[5] += width;
  P->counters[6] += 1;
}

int64_t lane_paths(Paths *P) {
  if (!P->started) {
    P->started = 1, P->taken = 0, P->current = -1, P->parts = 1, P->in_round = 0;
    for (int l = 0; l < L; l++) P->path[l] = -1, P->loaded[l] = -1;
  }
  for (;;) {
    if (!P->in_round) {
      take_paths(P);
      int width = gather(P);
      if (width == 0) {
        if (P->taken == P->count) {
          int empty = 1;
          for (int p = 0; p < L; p++) empty &= P->path[p] < 0;
          if (empty) return PATHS_DONE;
        }
        P->current = -1;  /* every path of the scene is done: the next scene's */
        continue;
      }
      bound_round(P, width);
      P->width = width, P->lane = 0, P->in_round = 1, P->resume = 0;
    }
    for (; P->lane < P->width; P->lane++) {
      int64_t l = P->lane, p = P->owner[l];
      int64_t n = P->grid[p], a = P->lo[l], b = P->hi[l], i = P->mid[l];
      double step = P->block->step[l];
      if (P->resume) {
        P->resume = 0;  /* the scalar kernel's step */
      } else {
        if (i >= P->found[p] || (!P->first && P->found[p] <= n))
          continue;  /* above a contact found this round, or the verdict is in */
        if (step == CONTACT) {
          P->counters[7] += 1;
        } else if (step < 0.0) {
          P->resume = 1;
          return PATHS_SCALAR;
        }
      }
      if (step < 0.0) {
        P->found[p] = i;
        if (!P->first) P->head[p] = P->tail[p];
        else P->tail[p] = push_interval(P, p, P->tail[p], a, i - 1);
        continue;
      }
      double scaled = MAX(step, 0.0) * (double)n;
      int64_t reach = scaled >= (double)n ? n : (int64_t)scaled;
      P->tail[p] = push_interval(P, p, P->tail[p], a, i - reach - 1);
      P->tail[p] = push_interval(P, p, P->tail[p], i + reach + 1, b);
    }
    P->in_round = 0;
  }
}
