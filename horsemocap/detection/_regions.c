/*
 * Compiled core of the candidate search (issue 16): horsemocap.detection._regions.
 *
 * One call does, for a list of crops of one gray image, what the Python path
 * of horsemocap.detection.identification does for them (frame_candidates with
 * a crop, _whole_frame_search on the crops of thresholds.bright_crops):
 * threshold (eq. 4.5: white when I > l), 8-connected labelling, per-region
 * area / box / border flags / crop-edge drop, the area range, circularity
 * (filters.region_circularity, the same formula and the same path as the
 * Python code would take), the labelling order of OpenCV's block-based
 * algorithm (CCL_BBDT: a region's number follows the first 2 x 2 block it
 * reaches in raster order of blocks), the max_count largest, and the centres:
 * the intensity-weighted centroid above the local background
 * (filters.region_weights / weighted_centroids, the symmetric border of
 * filters._symmetric_in_image) and, when asked, filters.light_terms.
 * The Python path is the reference (tests/test_regions_core.py runs both).
 *
 * Only Python's headers are needed (buffer protocol, no NumPy C API). The GIL
 * is released around the pure C part. Built with -ffp-contract=off so that
 * each floating expression is rounded as Python rounds it.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#if defined(_MSC_VER) && !defined(restrict)
#define restrict __restrict
#endif

/* The hash of this file, given by setup.py: regions_core.py refuses a core built from another version
   of it (a stale build left beside the source by an editable install). */
#ifndef CORE_SOURCE_HASH
#define CORE_SOURCE_HASH ""
#endif

#define MARGIN 2          /* filters.region_weights' margin (the identification's default) */
#define MIN_INNER 5       /* filters.light_terms' min_inner */
#define SYM_ITERATIONS 5  /* filters._symmetric_in_image's iterations */
#define MOMENTS_UP_TO 8   /* filters.region_circularity: up to 8 regions by cv2.moments */

typedef struct {
    int64_t area, sx, sy, sxx, syy;   /* crop-local pixel sums */
    int x0, y0, x1, y1;               /* crop-local box, inclusive */
    int64_t key;                      /* first 2 x 2 block reached: block row << 32 | block column */
} Comp;

typedef struct {
    int u0, v0, u1, v1, w, h;
    int32_t *lab;                     /* provisional label per pixel, resolved to a component index + 1 */
    Comp *comp;
    int n;
} Crop;

typedef struct {
    int crop, comp;                   /* crop index, component index in it */
    int64_t key, area;
    Py_ssize_t seq;                   /* position before sorting (stable sorts) */
} Cand;

enum { OK = 0, NO_MEMORY = 1, FALLBACK = 2 };

/* ------------------------------------------------------------------------ */
/* labelling                                                                 */
/* ------------------------------------------------------------------------ */
static int32_t find_root(int32_t *parent, int32_t a)
{
    int32_t r = a;
    while (parent[r] != r)
        r = parent[r];
    while (parent[a] != r) {          /* path compression */
        int32_t next = parent[a];
        parent[a] = r;
        a = next;
    }
    return r;
}

static void unite(int32_t *parent, int32_t a, int32_t b)
{
    a = find_root(parent, a);
    b = find_root(parent, b);
    if (a < b)
        parent[b] = a;
    else if (b < a)
        parent[a] = b;
}

static int chunk_has_white(const uint8_t *p, int thr)
{
    unsigned any = 0;
    for (int i = 0; i < 16; i++)
        any |= (unsigned)((int)p[i] > thr);
    return any != 0;
}

/* First pass of the labelling of (img > thr), img: the area's top-left pixel, rows stride apart: provisional
 * labels (lab, 0 = black) and their union-find forest (*parent, nl labels); row_lo/row_hi: each row's first
 * and last white column (lo > hi: none). Runs of 16 black pixels are skipped at once. */
static int first_pass(const uint8_t *img, Py_ssize_t stride, int w, int h, int thr, int32_t *lab, int *row_lo,
                      int *row_hi, int32_t **parent_out, int32_t *nl_out)
{
    int32_t cap = 256, nl = 0;
    int32_t *parent = malloc(sizeof(int32_t) * cap);
    *parent_out = NULL;
    if (!parent)
        return NO_MEMORY;
    for (int y = 0; y < h; y++) {
        const uint8_t *row = img + (Py_ssize_t)y * stride;
        int32_t *L = lab + (size_t)y * w;
        const int32_t *P = y > 0 ? L - w : NULL;
        memset(L, 0, sizeof(int32_t) * (size_t)w);
        row_lo[y] = w;
        row_hi[y] = -1;
        for (int x = 0; x < w;) {
            if (x + 16 <= w && !chunk_has_white(row + x, thr)) {
                x += 16;
                continue;
            }
            int end = x + 16 <= w ? x + 16 : w;
            for (; x < end; x++) {
                if ((int)row[x] <= thr) continue;
                if (x < row_lo[y]) row_lo[y] = x;
                row_hi[y] = x;
                int32_t nb[4] = {x > 0 ? L[x - 1] : 0, (P && x > 0) ? P[x - 1] : 0, P ? P[x] : 0,
                                 (P && x + 1 < w) ? P[x + 1] : 0};
                int32_t l = 0;
                for (int k = 0; k < 4; k++) {
                    if (!nb[k]) continue;
                    if (!l) l = nb[k];
                    else if (nb[k] != l) unite(parent, l, nb[k]);
                }
                if (!l) {
                    if (nl + 1 >= cap) {
                        int32_t *np2 = realloc(parent, sizeof(int32_t) * (size_t)cap * 2);
                        if (!np2) {
                            free(parent);
                            return NO_MEMORY;
                        }
                        parent = np2;
                        cap *= 2;
                    }
                    l = ++nl;
                    parent[l] = l;
                }
                L[x] = l;
            }
        }
    }
    *parent_out = parent;
    *nl_out = nl;
    return OK;
}

/* Second pass of the labelling: the components of the provisional labels lab (w x h, white pixels only
   between row_lo and row_hi of each row), numbered by their first pixel in raster order, lab rewritten to
   component index + 1; their pixel sums, boxes and keys (the first 2 x 2 block reached, on the block grid
   shifted by (ox, oy)). *comp_out: n components (at most nl), freed by the caller. */
static int second_pass(int32_t *lab, int w, int h, const int *row_lo, const int *row_hi, int32_t *parent,
                       int32_t nl, int ox, int oy, Comp **comp_out, int *n_out)
{
    int32_t *index = calloc((size_t)nl + 1, sizeof(int32_t));
    Comp *comp = malloc(sizeof(Comp) * ((size_t)nl + 1));
    if (!index || !comp) {
        free(index);
        free(comp);
        return NO_MEMORY;
    }
    int n = 0;
    for (int y = 0; y < h; y++) {
        int32_t *L = lab + (size_t)y * w;
        const int64_t by = (int64_t)((y + oy) >> 1) << 32;
        for (int x = row_lo[y]; x <= row_hi[y]; x++) {
            if (!L[x])
                continue;
            int32_t r = find_root(parent, L[x]);
            if (!index[r]) {
                Comp *k = &comp[n];
                memset(k, 0, sizeof(Comp));
                k->x0 = k->x1 = x;
                k->y0 = k->y1 = y;
                k->key = INT64_MAX;
                index[r] = ++n;
            }
            int32_t id = index[r];
            Comp *k = &comp[id - 1];
            L[x] = id;
            k->area++;
            k->sx += x;
            k->sy += y;
            k->sxx += (int64_t)x * x;
            k->syy += (int64_t)y * y;
            if (x < k->x0) k->x0 = x;
            if (x > k->x1) k->x1 = x;
            k->y1 = y;
            int64_t key = by | (int64_t)((x + ox) >> 1);
            if (key < k->key) k->key = key;
        }
    }
    free(index);
    *comp_out = comp;
    *n_out = n;
    return OK;
}

/* 8-connected labels of (g > thr) in the crop; keys on the block grid shifted by (ox, oy). */
static int label_crop(const uint8_t *img, Py_ssize_t stride, int thr, int ox, int oy, Crop *c)
{
    const int w = c->w, h = c->h;
    int32_t nl = 0, *parent = NULL;
    int *row_lo = malloc(sizeof(int) * (size_t)h), *row_hi = malloc(sizeof(int) * (size_t)h);
    int status = NO_MEMORY;
    c->lab = malloc(sizeof(int32_t) * (size_t)w * (size_t)h);
    c->comp = NULL;
    c->n = 0;
    if (row_lo && row_hi && c->lab
            && first_pass(img + (Py_ssize_t)c->v0 * stride + c->u0, stride, w, h, thr, c->lab, row_lo, row_hi,
                          &parent, &nl) == OK)
        status = second_pass(c->lab, w, h, row_lo, row_hi, parent, nl, ox, oy, &c->comp, &c->n);
    free(parent);
    free(row_lo);
    free(row_hi);
    return status;
}

/* ------------------------------------------------------------------------ */
/* circularity: filters.region_circularity                                   */
/* ------------------------------------------------------------------------ */
static double circ_by_moments(const Comp *k)
{   /* cv2.moments of the region's box (binary): integer raw moments, then cv::Moments' central ones */
    const int64_t a = k->area, bx = k->x0, by = k->y0;
    const double m00 = (double)a;
    const double m10 = (double)(k->sx - bx * a), m01 = (double)(k->sy - by * a);
    const double m20 = (double)(k->sxx - 2 * bx * k->sx + bx * bx * a);
    const double m02 = (double)(k->syy - 2 * by * k->sy + by * by * a);
    double cx = 0, cy = 0;
    if (fabs(m00) > 2.220446049250313e-16) {
        double inv = 1. / m00;
        cx = m10 * inv;
        cy = m01 * inv;
    }
    double mu20 = m20 - m10 * cx, mu02 = m02 - m01 * cy;
    double var = (mu20 + mu02) / m00 + 1.0 / 6.0;
    return m00 / (2 * Py_MATH_PI * var);
}

static double circ_by_sums(const Comp *k, int64_t du, int64_t dv)
{   /* the sums of u = x + du, v = y + dv over the region's pixels (exact integers) */
    const int64_t a = k->area;
    const double A = (double)a;
    const double su = (double)(k->sx + du * a), sv = (double)(k->sy + dv * a);
    const double suu = (double)(k->sxx + 2 * du * k->sx + du * du * a);
    const double svv = (double)(k->syy + 2 * dv * k->sy + dv * dv * a);
    double var = (suu - su * su / A + svv - sv * sv / A) / A + 1.0 / 6.0;
    return A / (2 * Py_MATH_PI * var);
}

/* ------------------------------------------------------------------------ */
/* centres: filters.region_weights, weighted_centroids, light_terms          */
/* ------------------------------------------------------------------------ */
typedef struct {
    double cu, cv;                    /* centre, full-image pixels */
    double slope[2], mom[4];          /* light terms (NaN when not measured) */
} Centre;

static void min_of_rows(const uint8_t *restrict row_d, int pw, int ph, int y, int cap, uint8_t *restrict out)
{
    memcpy(out, row_d + (size_t)y * pw, (size_t)pw);
    for (int dy = 1; dy <= cap; dy++) {
        for (int side = -1; side <= 1; side += 2) {
            const int yy = y + side * dy;
            if (yy < 0 || yy >= ph)
                continue;
            const uint8_t *restrict src = row_d + (size_t)yy * pw;
            const uint8_t ady = (uint8_t)dy;
            for (int x = 0; x < pw; x++) {
                uint8_t v = src[x] > ady ? src[x] : ady;
                out[x] = v < out[x] ? v : out[x];
            }
        }
    }
}

/* Chebyshev distance (capped at cap) of each patch pixel to the nearest set pixel of mask, inside the patch. */
static void cheb_distance(const uint8_t *mask, int pw, int ph, int cap, uint8_t *row_d, uint8_t *d)
{
    for (int y = 0; y < ph; y++) {
        const uint8_t *m = mask + (size_t)y * pw;
        uint8_t *r = row_d + (size_t)y * pw;
        int last = -100000;
        for (int x = 0; x < pw; x++) {
            if (m[x]) last = x;
            int dd = x - last;
            r[x] = (uint8_t)(dd > cap ? cap + 1 : dd);
        }
        last = 100000;
        for (int x = pw - 1; x >= 0; x--) {
            if (m[x]) last = x;
            int dd = last - x;
            if (dd < r[x]) r[x] = (uint8_t)dd;
        }
    }
    for (int y = 0; y < ph; y++)        /* d = min over |dy| <= cap of max(|dy|, row distance at y + dy) */
        min_of_rows(row_d, pw, ph, y, cap, d + (size_t)y * pw);
}

static double clip_half(double t)
{
    return t < -0.5 ? -0.5 : (t > 0.5 ? 0.5 : t);
}

/* NumPy's pairwise summation of a[0..n) (ndarray.sum of a contiguous array): sums in filters.py's NumPy code
 * and here rounded alike. */
static double pairwise_sum(const double *a, Py_ssize_t n)
{
    if (n < 8) {
        double res = 0.;
        for (Py_ssize_t i = 0; i < n; i++)
            res += a[i];
        return res;
    }
    if (n <= 128) {
        double r[8], res;
        Py_ssize_t i;
        for (int k = 0; k < 8; k++)
            r[k] = a[k];
        for (i = 8; i < n - (n % 8); i += 8)
            for (int k = 0; k < 8; k++)
                r[k] += a[i + k];
        res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]));
        for (; i < n; i++)
            res += a[i];
        return res;
    }
    Py_ssize_t n2 = n / 2;
    n2 -= n2 % 8;
    return pairwise_sum(a, n2) + pairwise_sum(a + n2, n - n2);
}

/* filters._symmetric_1d */
static double symmetric_1d(const double *p, int n, double x0, double c, int cut_low, int cut_high, double N,
                           double *slope, double *mass, double *moment)
{
    if (!(cut_low || cut_high))
        return c;
    if (n > 1) {
        slope[0] = p[1] - p[0];
        slope[n - 1] = p[n - 1] - p[n - 2];
        for (int i = 1; i < n - 1; i++)
            slope[i] = (p[i + 1] - p[i - 1]) / 2.0;
    } else {
        slope[0] = 0.0;
    }
    for (int it = 0; it < SYM_ITERATIONS; it++) {
        double lo = cut_high ? 2 * c - (N - 0.5) : -INFINITY;
        double hi = cut_low ? 2 * c + 0.5 : INFINITY;
        for (int i = 0; i < n; i++) {
            double x = x0 + i;
            double t0 = clip_half(lo - x), t1 = clip_half(hi - x);
            if (t1 < t0) t1 = t0;
            double d2 = t1 * t1 - t0 * t0, d3 = pow(t1, 3.0) - pow(t0, 3.0);   /* NumPy: square, and pow */
            mass[i] = p[i] * (t1 - t0) + slope[i] * d2 / 2;
            moment[i] = x * mass[i] + p[i] * d2 / 2 + slope[i] * d3 / 3;
        }
        double s = pairwise_sum(mass, n);
        if (!(s > 0))
            break;
        c = pairwise_sum(moment, n) / s;
    }
    return c;
}

/* The unsigned 128-bit product of a and b as (hi, lo), in portable C. */
static void mul_u64(uint64_t a, uint64_t b, uint64_t *hi, uint64_t *lo)
{
    uint64_t a0 = a & 0xffffffffu, a1 = a >> 32, b0 = b & 0xffffffffu, b1 = b >> 32;
    uint64_t p00 = a0 * b0, p01 = a0 * b1, p10 = a1 * b0, p11 = a1 * b1;
    uint64_t mid = (p00 >> 32) + (p01 & 0xffffffffu) + (p10 & 0xffffffffu);
    *lo = (mid << 32) | (p00 & 0xffffffffu);
    *hi = p11 + (p01 >> 32) + (p10 >> 32) + (mid >> 32);
}

/* 1 when the pixels of these sums are certainly not on one line: dx dy != dxy^2 exactly (Python's
   filters._plane decides it with unbounded integers), with dx = n sxx - sx^2, dy = n syy - sy^2,
   dxy = n sxy - sx sy (n^2 times the covariances, so 0 <= dxy^2 <= dx dy). Each is taken modulo 2^64,
   which is exact while it lies below 2^62 (checked in double precision, whose error here is far below
   2^61); larger sums (over a million pixels spread over thousands of columns) give 0: the caller then
   leaves the region to the Python path. */
static int exactly_not_collinear(int64_t n, int64_t sx, int64_t sy, int64_t sxx, int64_t sxy, int64_t syy)
{
    const double N = (double)n, lim = 4611686018427387904.0;   /* 2^62 */
    double ddx = N * (double)sxx - (double)sx * (double)sx, ddy = N * (double)syy - (double)sy * (double)sy;
    if (!(ddx < lim / 2 && ddy < lim / 2))
        return 0;
    uint64_t dx = (uint64_t)n * (uint64_t)sxx - (uint64_t)sx * (uint64_t)sx;
    uint64_t dy = (uint64_t)n * (uint64_t)syy - (uint64_t)sy * (uint64_t)sy;
    int64_t dxy = (int64_t)((uint64_t)n * (uint64_t)sxy - (uint64_t)sx * (uint64_t)sy);
    uint64_t adxy = dxy < 0 ? (uint64_t)0 - (uint64_t)dxy : (uint64_t)dxy;
    uint64_t h1, l1, h2, l2;
    mul_u64(dx, dy, &h1, &l1);
    mul_u64(adxy, adxy, &h2, &l2);
    return h1 != h2 || l1 != l2;
}

/* filters._plane: (a, gu, gv), or FALLBACK when the interior pixels lie on one line */
static int plane(int64_t n, int64_t sx, int64_t sy, int64_t sxx, int64_t sxy, int64_t syy, double z, double zx,
                 double zy, double cu, double cv, double *out)
{
    if (!exactly_not_collinear(n, sx, sy, sxx, sxy, syy))
        return FALLBACK;
    const double N = (double)n;
    double ex = (double)sx - N * cu, ey = (double)sy - N * cv;
    double exx = (double)sxx - 2 * cu * (double)sx + N * cu * cu;
    double eyy = (double)syy - 2 * cv * (double)sy + N * cv * cv;
    double exy = (double)sxy - cu * (double)sy - cv * (double)sx + N * cu * cv;
    double bz = z, bx = zx - cu * z, by = zy - cv * z;
    double c00 = exx * eyy - exy * exy, c01 = ey * exy - ex * eyy, c02 = ex * exy - ey * exx;
    double c11 = N * eyy - ey * ey, c12 = ex * ey - N * exy, c22 = N * exx - ex * ex;
    double det = N * c00 + ex * c01 + ey * c02;
    out[0] = (c00 * bz + c01 * bx + c02 * by) / det;
    out[1] = (c01 * bz + c11 * bx + c12 * by) / det;
    out[2] = (c02 * bz + c12 * bx + c22 * by) / det;
    return OK;
}

/* The centre (and light terms) of component ci of crop c; g: the full gray image. */
static int region_centre(const uint8_t *g, Py_ssize_t stride, const Crop *c, int ci, int W, int H, int light,
                         double binary_u, double binary_v, Centre *out)
{
    const Comp *k = &c->comp[ci];
    const int id = ci + 1, G = 2 * MARGIN + 2;
    const int bw = k->x1 - k->x0 + 1, bh = k->y1 - k->y0 + 1;
    const int x0 = k->x0 - G > 0 ? k->x0 - G : 0, y0 = k->y0 - G > 0 ? k->y0 - G : 0;
    const int x1 = k->x0 + bw + G < c->w ? k->x0 + bw + G : c->w;
    const int y1 = k->y0 + bh + G < c->h ? k->y0 + bh + G : c->h;
    const int pw = x1 - x0, ph = y1 - y0;
    const size_t np = (size_t)pw * ph;
    int status = OK;
    for (int i = 0; i < 2; i++) out->slope[i] = NAN;
    for (int i = 0; i < 4; i++) out->mom[i] = NAN;
    uint8_t *buf = malloc(np * 6);
    double *wgt = malloc(sizeof(double) * (np + 4 * (size_t)(pw > ph ? pw : ph)));
    if (!buf || !wgt) {
        free(buf);
        free(wgt);
        return NO_MEMORY;
    }
    uint8_t *own = buf, *other = buf + np, *d_own = buf + 2 * np, *d_other = buf + 3 * np, *tmp = buf + 4 * np;
    uint8_t *sub = buf + 5 * np;
    int64_t labelled = 0;
    for (int y = 0; y < ph; y++) {
        const int32_t *L = c->lab + (size_t)(y0 + y) * c->w + x0;
        const uint8_t *gr = g + (Py_ssize_t)(c->v0 + y0 + y) * stride + c->u0 + x0;
        for (int x = 0; x < pw; x++) {
            size_t p = (size_t)y * pw + x;
            own[p] = L[x] == id;
            other[p] = L[x] != 0 && L[x] != id;
            labelled += L[x] != 0;
            sub[p] = gr[x];
        }
    }
    cheb_distance(own, pw, ph, MARGIN + 2, tmp, d_own);       /* near: <= MARGIN, far: <= MARGIN + 2 */
    const int others = labelled > k->area;
    if (others)
        cheb_distance(other, pw, ph, 1, tmp, d_other);         /* the other regions grown by one */
    /* background: the median of the ring (far, not near, not the grown other regions) */
    int64_t hist[256] = {0}, nring = 0;
    int own_min = 256;
    for (size_t p = 0; p < np; p++) {
        int near = d_own[p] <= MARGIN, far = d_own[p] <= MARGIN + 2;
        int oth = others && d_other[p] <= 1;
        if (far && !near && !oth) {
            hist[sub[p]]++;
            nring++;
        }
        if (own[p] && sub[p] < own_min) own_min = sub[p];
    }
    double b;
    if (nring) {
        int64_t want[2] = {nring % 2 ? nring / 2 : nring / 2 - 1, nring / 2}, acc = 0;
        int val[2] = {-1, -1};
        for (int v = 0; v < 256 && val[1] < 0; v++) {
            acc += hist[v];
            for (int j = 0; j < 2; j++)
                if (val[j] < 0 && acc > want[j]) val[j] = v;
        }
        b = nring % 2 ? (double)val[1] : ((double)val[0] + (double)val[1]) / 2;
    } else {
        b = (double)own_min - 1;
    }
    /* weights max(I - b, 0) on near (other regions' grown pixels left out), their moments */
    double m00 = 0, m10 = 0, m01 = 0, m20 = 0, m11 = 0, m02 = 0;
    for (int y = 0; y < ph; y++) {
        for (int x = 0; x < pw; x++) {
            size_t p = (size_t)y * pw + x;
            int near = d_own[p] <= MARGIN && !(others && d_other[p] <= 1 && !own[p]);
            double above = (double)sub[p] - b;
            double wv = near && above > 0 ? above : 0.0;
            wgt[p] = wv;
            if (wv != 0.0) {
                m00 += wv;
                m10 += x * wv;
                m01 += y * wv;
                m20 += (double)x * x * wv;
                m11 += (double)x * y * wv;
                m02 += (double)y * y * wv;
            }
        }
    }
    const int ou = x0 + c->u0, ov = y0 + c->v0;
    if (!(m00 > 0)) {
        out->cu = binary_u;
        out->cv = binary_v;
        goto done;
    }
    out->cu = (m10 + ou * m00) / m00;
    out->cv = (m01 + ov * m00) / m00;
    const int bxi = k->x0 + c->u0, byi = k->y0 + c->v0;
    const int cut[4] = {bxi <= 0, bxi + bw >= W, byi <= 0, byi + bh >= H};
    if (cut[0] || cut[1] || cut[2] || cut[3]) {
        const size_t side = (size_t)(pw > ph ? pw : ph);
        double *prof = wgt + np, *slope = prof + side, *mass = slope + side, *moment = mass + side;
        if (cut[0] || cut[1]) {
            for (int x = 0; x < pw; x++) prof[x] = 0.0;
            for (int y = 0; y < ph; y++)
                for (int x = 0; x < pw; x++) prof[x] += wgt[(size_t)y * pw + x];
            out->cu = symmetric_1d(prof, pw, (double)ou, out->cu, cut[0], cut[1], (double)W, slope, mass, moment);
        }
        if (cut[2] || cut[3]) {
            for (int y = 0; y < ph; y++) {
                double s = 0.0;
                for (int x = 0; x < pw; x++) s += wgt[(size_t)y * pw + x];
                prof[y] = s;
            }
            out->cv = symmetric_1d(prof, ph, (double)ov, out->cv, cut[2], cut[3], (double)H, slope, mass, moment);
        }
    }
    if (!light)
        goto done;
    {
        double inv = 1. / m00, cx = m10 * inv, cy = m01 * inv;
        double mu20 = m20 - m10 * cx, mu11 = m11 - m10 * cy, mu02 = m02 - m01 * cy;
        double suv = mu11 / m00;
        out->mom[0] = mu20 / m00;
        out->mom[1] = suv;
        out->mom[2] = suv;
        out->mom[3] = mu02 / m00;
        if (cut[0] || cut[1] || cut[2] || cut[3])
            goto done;
        /* interior: own eroded by 3 x 3 (outside the patch: 0); its moments and its heights' */
        int64_t n = 0, sx = 0, sy = 0, sxx = 0, sxy = 0, syy = 0;
        double z = 0, zx = 0, zy = 0;
        for (int y = 1; y < ph - 1; y++) {
            for (int x = 1; x < pw - 1; x++) {
                int inside = 1;
                for (int dy = -1; dy <= 1 && inside; dy++)
                    for (int dx = -1; dx <= 1; dx++)
                        if (!own[(size_t)(y + dy) * pw + x + dx]) {
                            inside = 0;
                            break;
                        }
                if (!inside)
                    continue;
                n++;
                sx += x;
                sy += y;
                sxx += (int64_t)x * x;
                sxy += (int64_t)x * y;
                syy += (int64_t)y * y;
                double h = (double)(float)((double)sub[(size_t)y * pw + x] - b);
                z += h;
                zx += x * h;
                zy += y * h;
            }
        }
        if (n < MIN_INNER)
            goto done;
        double sol[3];
        if (plane(n, sx, sy, sxx, sxy, syy, z, zx, zy, m10 / m00, m01 / m00, sol) != OK) {
            status = FALLBACK;          /* least squares (minimum norm): left to the Python path */
            goto done;
        }
        if (sol[0] > 0) {
            out->slope[0] = sol[1] / sol[0];
            out->slope[1] = sol[2] / sol[0];
        }
    }
done:
    free(buf);
    free(wgt);
    return status;
}

/* ------------------------------------------------------------------------ */
/* the call                                                                   */
/* ------------------------------------------------------------------------ */
typedef struct {
    /* in */
    const uint8_t *g;
    Py_ssize_t stride;
    int W, H, thr, ncrops, whole, max_count, weighted, light, has_circ;
    double amin, amax, min_circ;
    Crop *crops;
    /* out */
    Cand *sel;
    Py_ssize_t nsel;
    Centre *centres;
    double *binary;                    /* (nsel, 2) binary centres */
} Job;

static int by_key(const void *a, const void *b)
{
    const Cand *p = a, *q = b;
    if (p->key != q->key) return p->key < q->key ? -1 : 1;
    return p->seq < q->seq ? -1 : (p->seq > q->seq);
}

static int by_area_desc(const void *a, const void *b)
{
    const Cand *p = a, *q = b;
    if (p->area != q->area) return p->area > q->area ? -1 : 1;
    return p->seq < q->seq ? -1 : (p->seq > q->seq);
}

static int run_job(Job *j)
{
    int status;
    Py_ssize_t cap = 16, nc = 0;
    Cand *cands = malloc(sizeof(Cand) * cap);
    if (!cands) return NO_MEMORY;
    for (int i = 0; i < j->ncrops; i++) {
        Crop *c = &j->crops[i];
        if (c->w <= 0 || c->h <= 0) continue;
        status = label_crop(j->g, j->stride, j->thr, j->whole ? c->u0 : 0, j->whole ? c->v0 : 0, c);
        if (status != OK) goto fail;
        /* a region cut by a crop edge that is not an image edge is dropped (frame_candidates) */
        const int lo_u = c->u0 > 0 ? c->u0 : -1, lo_v = c->v0 > 0 ? c->v0 : -1;
        const int64_t hi_u = c->u1 < j->W ? c->u1 : INT64_MAX, hi_v = c->v1 < j->H ? c->v1 : INT64_MAX;
        for (int ci = 0; ci < c->n; ci++) {
            const Comp *k = &c->comp[ci];
            const double a = (double)k->area;
            if (!(j->amin <= a && a <= j->amax)) continue;
            if (!j->whole) {
                const int x = k->x0 + c->u0, y = k->y0 + c->v0;
                const int64_t xe = (int64_t)k->x1 + 1 + c->u0, ye = (int64_t)k->y1 + 1 + c->v0;
                if (!(x > lo_u && y > lo_v && xe < hi_u && ye < hi_v)) continue;
            }
            if (nc == cap) {
                Cand *n2 = realloc(cands, sizeof(Cand) * (size_t)cap * 2);
                if (!n2) { status = NO_MEMORY; goto fail; }
                cands = n2;
                cap *= 2;
            }
            cands[nc].crop = i;
            cands[nc].comp = ci;
            cands[nc].key = k->key;
            cands[nc].area = k->area;
            nc++;
        }
    }
    /* circularity: by moments up to 8 regions, else by sums (crop-local; whole: full-image pixels) */
    if (j->has_circ && nc) {
        Py_ssize_t kept = 0;
        const int moments = nc <= MOMENTS_UP_TO;
        for (Py_ssize_t q = 0; q < nc; q++) {
            const Crop *c = &j->crops[cands[q].crop];
            const Comp *k = &c->comp[cands[q].comp];
            double circ = moments ? circ_by_moments(k)
                                  : circ_by_sums(k, j->whole ? c->u0 : 0, j->whole ? c->v0 : 0);
            if (circ >= j->min_circ) cands[kept++] = cands[q];
        }
        nc = kept;
    }
    /* OpenCV's labelling order (stable: crops in turn, regions by first pixel), then the largest */
    for (Py_ssize_t q = 0; q < nc; q++) cands[q].seq = q;
    qsort(cands, (size_t)nc, sizeof(Cand), by_key);
    if (nc > j->max_count) {
        for (Py_ssize_t q = 0; q < nc; q++) cands[q].seq = q;
        qsort(cands, (size_t)nc, sizeof(Cand), by_area_desc);
        nc = j->max_count;
    }
    j->sel = cands;
    j->nsel = nc;
    j->centres = calloc(nc ? (size_t)nc : 1, sizeof(Centre));
    j->binary = malloc(sizeof(double) * 2 * (nc ? nc : 1));
    if (!j->centres || !j->binary) return NO_MEMORY;
    for (Py_ssize_t q = 0; q < nc; q++) {
        const Crop *c = &j->crops[cands[q].crop];
        const Comp *k = &c->comp[cands[q].comp];
        double a = (double)k->area, bu, bv;
        if (j->whole) {         /* _bright_regions: (sum + origin * area) / area */
            bu = (double)(k->sx + (int64_t)c->u0 * k->area) / a;
            bv = (double)(k->sy + (int64_t)c->v0 * k->area) / a;
        } else {                /* label_regions: OpenCV's sum / area, plus the origin */
            bu = (double)k->sx / a + (double)c->u0;
            bv = (double)k->sy / a + (double)c->v0;
        }
        j->binary[2 * q] = bu;
        j->binary[2 * q + 1] = bv;
        if (j->weighted) {
            status = region_centre(j->g, j->stride, c, cands[q].comp, j->W, j->H, j->light, bu, bv, &j->centres[q]);
            if (status != OK) return status;
        }
    }
    return OK;
fail:
    free(cands);
    return status;
}

static void free_job(Job *j)
{
    for (int i = 0; i < j->ncrops; i++) {
        free(j->crops[i].lab);
        free(j->crops[i].comp);
    }
    free(j->crops);
    free(j->sel);
    free(j->centres);
    free(j->binary);
}

static int as_int(PyObject *o, int *out, const char *what)
{
    long v = PyLong_AsLong(o);
    if (v == -1 && PyErr_Occurred()) {
        PyErr_Clear();
        PyErr_Format(PyExc_ValueError, "_regions.candidates: %s must be an integer", what);
        return -1;
    }
    if (v < INT32_MIN || v > INT32_MAX) {
        PyErr_Format(PyExc_ValueError, "_regions.candidates: %s out of range", what);
        return -1;
    }
    *out = (int)v;
    return 0;
}

static PyObject *new_bytes(const void *data, Py_ssize_t n)
{
    return PyByteArray_FromStringAndSize((const char *)data, n);
}

/* The gray image argument of every entry point: a 2-D uint8 buffer whose rows are contiguous (C-contiguous
   when c_contiguous), at most 2^28 pixels (32-bit labels and sums). 0, or -1 with a ValueError naming fn
   and the buffer released. */
static int gray_buffer(PyObject *obj, Py_buffer *view, int c_contiguous, const char *fn)
{
    if (PyObject_GetBuffer(obj, view, (c_contiguous ? PyBUF_C_CONTIGUOUS : PyBUF_STRIDES) | PyBUF_FORMAT) < 0) {
        PyErr_Clear();
        PyErr_Format(PyExc_ValueError, "%s: gray must be a %s", fn,
                     c_contiguous ? "C-contiguous buffer" : "buffer (a uint8 array)");
        return -1;
    }
    const char *why = NULL;
    if (view->ndim != 2 || view->itemsize != 1 || !view->format || strcmp(view->format, "B") != 0)
        why = "gray must be a 2-D uint8 array";
    else if (view->strides[1] != 1 || view->strides[0] < view->shape[1])
        why = "gray's rows must be contiguous (column stride 1)";
    else if (view->shape[0] > INT32_MAX / 2 || view->shape[1] > INT32_MAX / 2
             || view->shape[0] * view->shape[1] > INT32_MAX / 8)
        why = "gray too large (at most 2^28 pixels)";
    if (why) {
        PyErr_Format(PyExc_ValueError, "%s: %s", fn, why);
        PyBuffer_Release(view);
        return -1;
    }
    return 0;
}

PyDoc_STRVAR(candidates_doc,
"candidates(gray, threshold, crops, area_min, area_max, min_circularity, whole, max_count, weighted, light)\n"
"\n"
"Candidate regions of the crops [(u0, v0, u1, v1), ...] of gray (uint8, C-contiguous, 2-D).\n"
"whole=False: frame_candidates of one crop (crop-edge regions dropped, the crop's own labelling order);\n"
"whole=True: _whole_frame_search's crops (the whole image's labelling order).\n"
"Returns None when a region needs the Python path (light terms by least squares), else\n"
"(count, centre, area, cut, slope, moments) with bytearrays of float64 (count, 2), float64 (count,),\n"
"uint8 (count,), and float64 (count, 2), (count, 2, 2) or None (light and weighted only).");

static PyObject *candidates(PyObject *self, PyObject *args)
{
    PyObject *gray_obj, *crops_obj, *circ_obj;
    int thr, whole, max_count, weighted, light;
    double amin, amax;
    if (!PyArg_ParseTuple(args, "OiOddOpipp", &gray_obj, &thr, &crops_obj, &amin, &amax, &circ_obj, &whole,
                          &max_count, &weighted, &light))
        return NULL;
    if (max_count < 0) {
        PyErr_SetString(PyExc_ValueError, "_regions.candidates: max_count must be >= 0");
        return NULL;
    }
    if (isnan(amin) || isnan(amax)) {
        PyErr_SetString(PyExc_ValueError, "_regions.candidates: area range must not be NaN");
        return NULL;
    }
    Job j;
    memset(&j, 0, sizeof(j));
    if (circ_obj != Py_None) {
        j.min_circ = PyFloat_AsDouble(circ_obj);
        if (j.min_circ == -1.0 && PyErr_Occurred()) return NULL;
        j.has_circ = 1;
    }
    Py_buffer view;
    if (gray_buffer(gray_obj, &view, 1, "_regions.candidates") < 0)
        return NULL;
    PyObject *result = NULL, *seq = NULL;
    j.g = view.buf;
    j.H = (int)view.shape[0];
    j.W = (int)view.shape[1];
    j.stride = view.shape[1];
    j.thr = thr;
    j.whole = whole;
    j.max_count = max_count;
    j.weighted = weighted;
    j.light = light && weighted;
    j.amin = amin;
    j.amax = amax;
    seq = PySequence_Fast(crops_obj, "_regions.candidates: crops must be a sequence of (u0, v0, u1, v1)");
    if (!seq) goto out;
    Py_ssize_t nb = PySequence_Fast_GET_SIZE(seq);
    if (nb > INT32_MAX) {
        PyErr_SetString(PyExc_ValueError, "_regions.candidates: too many crops");
        goto out;
    }
    j.crops = calloc(nb ? (size_t)nb : 1, sizeof(Crop));
    if (!j.crops) { PyErr_NoMemory(); goto out; }
    j.ncrops = (int)nb;
    for (Py_ssize_t i = 0; i < nb; i++) {
        PyObject *box = PySequence_Fast(PySequence_Fast_GET_ITEM(seq, i), "_regions.candidates: a crop must be "
                                        "a sequence (u0, v0, u1, v1)");
        if (!box) goto out;
        int v[4];
        if (PySequence_Fast_GET_SIZE(box) != 4) {
            Py_DECREF(box);
            PyErr_Format(PyExc_ValueError, "_regions.candidates: crop %zd must have 4 values", i);
            goto out;
        }
        for (int q = 0; q < 4; q++)
            if (as_int(PySequence_Fast_GET_ITEM(box, q), &v[q], "a crop's corner") < 0) {
                Py_DECREF(box);
                goto out;
            }
        Py_DECREF(box);
        if (v[0] < 0 || v[1] < 0 || v[2] > j.W || v[3] > j.H || v[2] < v[0] || v[3] < v[1]) {
            PyErr_Format(PyExc_ValueError, "_regions.candidates: crop %zd (%d, %d, %d, %d) not inside the %d x %d "
                         "image (0 <= u0 <= u1 <= W, 0 <= v0 <= v1 <= H)", i, v[0], v[1], v[2], v[3], j.W, j.H);
            goto out;
        }
        Crop *c = &j.crops[i];
        c->u0 = v[0]; c->v0 = v[1]; c->u1 = v[2]; c->v1 = v[3];
        c->w = v[2] - v[0]; c->h = v[3] - v[1];
    }
    int status;
    Py_BEGIN_ALLOW_THREADS
    status = run_job(&j);
    Py_END_ALLOW_THREADS
    if (status == NO_MEMORY) { PyErr_NoMemory(); goto out; }
    if (status == FALLBACK) { result = Py_NewRef(Py_None); goto out; }
    {
        Py_ssize_t n = j.nsel;
        double *centre = malloc(sizeof(double) * 2 * (n ? n : 1)), *area = malloc(sizeof(double) * (n ? n : 1));
        uint8_t *cut = malloc(n ? n : 1);
        double *slope = malloc(sizeof(double) * 2 * (n ? n : 1)), *mom = malloc(sizeof(double) * 4 * (n ? n : 1));
        if (!centre || !area || !cut || !slope || !mom) {
            free(centre); free(area); free(cut); free(slope); free(mom);
            PyErr_NoMemory();
            goto out;
        }
        for (Py_ssize_t q = 0; q < n; q++) {
            const Crop *c = &j.crops[j.sel[q].crop];
            const Comp *k = &c->comp[j.sel[q].comp];
            centre[2 * q] = j.weighted ? j.centres[q].cu : j.binary[2 * q];
            centre[2 * q + 1] = j.weighted ? j.centres[q].cv : j.binary[2 * q + 1];
            area[q] = (double)k->area;
            const int bx = k->x0 + c->u0, by = k->y0 + c->v0;
            cut[q] = bx <= 0 || by <= 0 || bx + (k->x1 - k->x0 + 1) >= j.W || by + (k->y1 - k->y0 + 1) >= j.H;
            memcpy(slope + 2 * q, j.centres[q].slope, sizeof(double) * 2);
            memcpy(mom + 4 * q, j.centres[q].mom, sizeof(double) * 4);
        }
        PyObject *oc = new_bytes(centre, (Py_ssize_t)sizeof(double) * 2 * n);
        PyObject *oa = new_bytes(area, (Py_ssize_t)sizeof(double) * n);
        PyObject *ok = new_bytes(cut, n);
        PyObject *os = NULL, *om = NULL;
        if (j.light && n) {
            os = new_bytes(slope, (Py_ssize_t)sizeof(double) * 2 * n);
            om = new_bytes(mom, (Py_ssize_t)sizeof(double) * 4 * n);
        } else {
            os = Py_NewRef(Py_None);
            om = Py_NewRef(Py_None);
        }
        free(centre); free(area); free(cut); free(slope); free(mom);
        if (oc && oa && ok && os && om)
            result = Py_BuildValue("nNNNNN", n, oc, oa, ok, os, om);
        else {
            Py_XDECREF(oc); Py_XDECREF(oa); Py_XDECREF(ok); Py_XDECREF(os); Py_XDECREF(om);
        }
    }
out:
    Py_XDECREF(seq);
    PyBuffer_Release(&view);
    free_job(&j);
    return result;
}


/* ------------------------------------------------------------------------ */
/* label(): threshold + 8-connected labels + stats in one pass (the thesis chain's crops) */
/* ------------------------------------------------------------------------ */
typedef struct {
    const uint8_t *img;
    Py_ssize_t stride;
    int w, h, thr;
    int32_t *lab;                      /* out: labels in OpenCV's order */
    int32_t *stats;                    /* out: (n + 1, 5) */
    double *cents;                     /* out: (n + 1, 2) */
    int n;
} LabelJob;

static int by_comp_key(const void *a, const void *b)
{
    const int64_t *p = a, *q = b;     /* (key, temporary index) pairs */
    if (p[0] != q[0]) return p[0] < q[0] ? -1 : 1;
    return p[1] < q[1] ? -1 : (p[1] > q[1]);
}

static int label_fast(LabelJob *j)
{
    const int w = j->w, h = j->h;
    int32_t nl = 0, *parent = NULL;
    int *row_lo = malloc(sizeof(int) * (size_t)(h ? h : 1)), *row_hi = malloc(sizeof(int) * (size_t)(h ? h : 1));
    int32_t *final = NULL;
    Comp *comp = NULL;
    int64_t *order = NULL;
    int status = NO_MEMORY, n = 0;
    if (!row_lo || !row_hi || first_pass(j->img, j->stride, w, h, j->thr, j->lab, row_lo, row_hi, &parent, &nl) != OK
            || second_pass(j->lab, w, h, row_lo, row_hi, parent, nl, 0, 0, &comp, &n) != OK)
        goto out;
    /* OpenCV's numbering: by the first 2 x 2 block a region reaches */
    order = malloc(sizeof(int64_t) * 2 * (size_t)(n ? n : 1));
    final = malloc(sizeof(int32_t) * ((size_t)n + 1));
    j->stats = malloc(sizeof(int32_t) * 5 * ((size_t)n + 1));
    j->cents = malloc(sizeof(double) * 2 * ((size_t)n + 1));
    if (!order || !final || !j->stats || !j->cents) goto out;
    for (int q = 0; q < n; q++) {
        order[2 * q] = comp[q].key;
        order[2 * q + 1] = q;
    }
    qsort(order, (size_t)n, 2 * sizeof(int64_t), by_comp_key);
    int64_t fg = 0;
    final[0] = 0;
    for (int q = 0; q < n; q++) {
        int t = (int)order[2 * q + 1];
        const Comp *k = &comp[t];
        final[t + 1] = q + 1;
        int32_t *st = j->stats + 5 * (size_t)(q + 1);
        st[0] = k->x0;
        st[1] = k->y0;
        st[2] = k->x1 - k->x0 + 1;
        st[3] = k->y1 - k->y0 + 1;
        st[4] = (int32_t)k->area;
        j->cents[2 * (q + 1)] = (double)k->sx / (double)k->area;
        j->cents[2 * (q + 1) + 1] = (double)k->sy / (double)k->area;
        fg += k->area;
    }
    /* the background's row: its area; box (0, 0, w, h) and centre NaN (not OpenCV's: never used) */
    j->stats[0] = 0;
    j->stats[1] = 0;
    j->stats[2] = w;
    j->stats[3] = h;
    j->stats[4] = (int32_t)((int64_t)w * h - fg);
    j->cents[0] = j->cents[1] = NAN;
    for (int y = 0; y < h; y++) {
        int32_t *L = j->lab + (size_t)y * w;
        for (int x = row_lo[y]; x <= row_hi[y]; x++)
            L[x] = final[L[x]];
    }
    j->n = n + 1;
    status = OK;
out:
    free(parent);
    free(row_lo);
    free(row_hi);
    free(comp);
    free(order);
    free(final);
    return status;
}

PyDoc_STRVAR(label_doc,
"label(gray, threshold) -> (n, labels, stats, centroids)\n"
"\n"
"cv2.connectedComponentsWithStatsWithAlgorithm(gray > threshold, 8, CV_32S, CCL_BBDT) in one pass: n labels\n"
"(background included), labels int32 (h, w), stats int32 (n, 5) and centroids float64 (n, 2) as bytearrays,\n"
"the same numbers as OpenCV's for every region (row 0, the background: its area only; box (0, 0, w, h),\n"
"centre NaN). gray: 2-D uint8 whose rows are contiguous (a crop of a C-contiguous image is fine).");

static PyObject *label(PyObject *self, PyObject *args)
{
    PyObject *gray_obj, *result = NULL;
    int thr;
    if (!PyArg_ParseTuple(args, "Oi", &gray_obj, &thr))
        return NULL;
    Py_buffer view;
    if (gray_buffer(gray_obj, &view, 0, "_regions.label") < 0)
        return NULL;
    LabelJob j;
    memset(&j, 0, sizeof(j));
    PyObject *lab = NULL;
    j.img = view.buf;
    j.stride = view.strides[0];
    j.h = (int)view.shape[0];
    j.w = (int)view.shape[1];
    j.thr = thr;
    lab = PyByteArray_FromStringAndSize(NULL, (Py_ssize_t)sizeof(int32_t) * j.w * j.h);
    if (!lab) goto out;
    j.lab = (int32_t *)PyByteArray_AS_STRING(lab);
    int status;
    Py_BEGIN_ALLOW_THREADS
    status = label_fast(&j);
    Py_END_ALLOW_THREADS
    if (status != OK) {
        PyErr_NoMemory();
        goto out;
    }
    PyObject *st = new_bytes(j.stats, (Py_ssize_t)sizeof(int32_t) * 5 * j.n);
    PyObject *ce = new_bytes(j.cents, (Py_ssize_t)sizeof(double) * 2 * j.n);
    if (st && ce) {
        result = Py_BuildValue("iONN", j.n, lab, st, ce);
    } else {
        Py_XDECREF(st);
        Py_XDECREF(ce);
    }
out:
    Py_XDECREF(lab);
    free(j.stats);
    free(j.cents);
    PyBuffer_Release(&view);
    return result;
}

/* ------------------------------------------------------------------------ */
/* bright_boxes(): thresholds.bright_crops' crops, without the binary image  */
/* ------------------------------------------------------------------------ */
typedef struct { int u0, v0, u1, v1; } Box;

static int boxes_overlap(const Box *a, const Box *b)
{
    return a->u0 < b->u1 && b->u0 < a->u1 && a->v0 < b->v1 && b->v0 < a->v1;
}

static void column_max(const uint8_t *restrict g, Py_ssize_t stride, int W, int y0, int y1, uint8_t *restrict acc)
{
    if (W <= 0)
        return;
    memset(acc, 0, (size_t)W);
    for (int y = y0; y < y1; y++) {
        const uint8_t *restrict row = g + (Py_ssize_t)y * stride;
        for (int x = 0; x < W; x++)
            acc[x] = row[x] > acc[x] ? row[x] : acc[x];
    }
}

static void white_columns(uint8_t *restrict acc, int W, uint8_t t, int all)
{   /* acc: 1 where the column's brightest pixel is white (> t; every pixel when all) */
    if (W <= 0)
        return;
    if (all) {
        memset(acc, 1, (size_t)W);
        return;
    }
    for (int x = 0; x < W; x++)
        acc[x] = acc[x] > t;
}

/* the blocks holding a white pixel, labelled; their groups' padded boxes, overlapping ones merged */
static int bright_boxes_of(const uint8_t *g, Py_ssize_t stride, int W, int H, int thr, int block, int pad,
                           double max_fraction, Box **out, int *nout)
{
    const int Hb = (H + block - 1) / block, Wb = (W + block - 1) / block;
    uint8_t *small = calloc((size_t)Hb * Wb + 1, 1), *acc = malloc((size_t)W + 1);
    LabelJob j;
    memset(&j, 0, sizeof(j));
    Box *boxes = NULL, *merged = NULL;
    int status = NO_MEMORY, n = 0;
    *out = NULL;
    *nout = 0;
    if (!small || !acc) goto fail;
    if (thr < 255) {
        const int all = thr < 0;
        for (int by = 0; by < Hb; by++) {
            /* the brightest pixel of each column over the block's rows, then of each block */
            column_max(g, stride, W, by * block, by * block + block < H ? by * block + block : H, acc);
            white_columns(acc, W, all ? 0 : (uint8_t)thr, all);
            int bx = 0;
            if (block == 8)             /* a block's 8 columns as one 64-bit word */
                for (; bx < W / 8; bx++) {
                    uint64_t word;
                    memcpy(&word, acc + 8 * bx, 8);
                    small[(size_t)by * Wb + bx] = word != 0;
                }
            for (; bx < Wb; bx++) {
                uint8_t any = 0;
                for (int x = bx * block; x < bx * block + block && x < W; x++)
                    any |= acc[x];
                small[(size_t)by * Wb + bx] = any;
            }
        }
    }
    j.img = small;
    j.stride = Wb;
    j.w = Wb;
    j.h = Hb;
    j.thr = 0;
    j.lab = malloc(sizeof(int32_t) * ((size_t)Hb * Wb + 1));
    if (!j.lab || label_fast(&j) != OK) goto fail;
    n = j.n - 1;
    boxes = malloc(sizeof(Box) * (n ? n : 1));
    merged = malloc(sizeof(Box) * (n ? n : 1));
    if (!boxes || !merged) goto fail;
    for (int q = 0; q < n; q++) {
        const int32_t *st = j.stats + 5 * (q + 1);
        int64_t u0 = (int64_t)st[0] * block - pad, v0 = (int64_t)st[1] * block - pad;
        int64_t u1 = (int64_t)(st[0] + st[2]) * block + pad, v1 = (int64_t)(st[1] + st[3]) * block + pad;
        boxes[q].u0 = (int)(u0 > 0 ? u0 : 0);
        boxes[q].v0 = (int)(v0 > 0 ? v0 : 0);
        boxes[q].u1 = (int)(u1 < W ? u1 : W);
        boxes[q].v1 = (int)(v1 < H ? v1 : H);
    }
    int again = 1;
    while (again && n > 1) {           /* overlapping crops become one (thresholds._bright_boxes' loop) */
        again = 0;
        int m = 0;
        for (int q = 0; q < n; q++) {
            int into = -1;
            for (int o = 0; o < m; o++)
                if (boxes_overlap(&boxes[q], &merged[o])) {
                    into = o;
                    break;
                }
            if (into < 0) {
                merged[m++] = boxes[q];
                continue;
            }
            Box *o = &merged[into];
            if (boxes[q].u0 < o->u0) o->u0 = boxes[q].u0;
            if (boxes[q].v0 < o->v0) o->v0 = boxes[q].v0;
            if (boxes[q].u1 > o->u1) o->u1 = boxes[q].u1;
            if (boxes[q].v1 > o->v1) o->v1 = boxes[q].v1;
            again = 1;
        }
        Box *t = boxes;
        boxes = merged;
        merged = t;
        n = m;
    }
    int64_t covered = 0;
    for (int q = 0; q < n; q++)
        covered += (int64_t)(boxes[q].u1 - boxes[q].u0) * (boxes[q].v1 - boxes[q].v0);
    if ((double)covered > max_fraction * H * W) {
        n = 1;
        boxes[0].u0 = boxes[0].v0 = 0;
        boxes[0].u1 = W;
        boxes[0].v1 = H;
    }
    *out = boxes;
    *nout = n;
    boxes = NULL;
    status = OK;
fail:
    free(small);
    free(acc);
    free(j.lab);
    free(j.stats);
    free(j.cents);
    free(boxes);
    free(merged);
    return status;
}

PyDoc_STRVAR(bright_boxes_doc,
"bright_boxes(gray, threshold, block, pad, max_fraction) -> [[u0, v0, u1, v1], ...]\n"
"\n"
"thresholds.bright_crops(gray, threshold, block, pad)[1] (max_fraction: BRIGHT_MAX_FRACTION) without the\n"
"binary image: the same crops in the same order. gray: 2-D uint8, C-contiguous.");

static PyObject *bright_boxes(PyObject *self, PyObject *args)
{
    PyObject *gray_obj, *result = NULL;
    int thr, block, pad;
    double max_fraction;
    if (!PyArg_ParseTuple(args, "Oiiid", &gray_obj, &thr, &block, &pad, &max_fraction))
        return NULL;
    if (block < 1 || block > 4096 || pad < 0 || pad > 1 << 20 || isnan(max_fraction)) {
        PyErr_SetString(PyExc_ValueError, "_regions.bright_boxes: expected 1 <= block <= 4096, 0 <= pad, "
                        "max_fraction a number");
        return NULL;
    }
    Py_buffer view;
    if (gray_buffer(gray_obj, &view, 1, "_regions.bright_boxes") < 0)
        return NULL;
    Box *boxes;
    int n, status;
    const int H = (int)view.shape[0], W = (int)view.shape[1];
    Py_BEGIN_ALLOW_THREADS
    status = bright_boxes_of(view.buf, view.shape[1], W, H, thr, block, pad, max_fraction, &boxes, &n);
    Py_END_ALLOW_THREADS
    PyBuffer_Release(&view);
    if (status != OK)
        return PyErr_NoMemory();
    result = PyList_New(n);
    for (int q = 0; result && q < n; q++) {
        PyObject *b = Py_BuildValue("[iiii]", boxes[q].u0, boxes[q].v0, boxes[q].u1, boxes[q].v1);
        if (!b) {
            Py_CLEAR(result);
            break;
        }
        PyList_SET_ITEM(result, q, b);
    }
    free(boxes);
    return result;
}

static PyMethodDef methods[] = {
    {"bright_boxes", bright_boxes, METH_VARARGS, bright_boxes_doc},
    {"candidates", candidates, METH_VARARGS, candidates_doc},
    {"label", label, METH_VARARGS, label_doc},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_regions",
    "Compiled core of horsemocap.detection's candidate search (issue 16); the Python path is the reference.",
    -1, methods,
};

PyMODINIT_FUNC PyInit__regions(void)
{
    PyObject *m = PyModule_Create(&module);
    if (m && PyModule_AddStringConstant(m, "CORE_SOURCE_HASH", CORE_SOURCE_HASH) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
