/* Wahba's problem per frame (keyframes.Compensation's rotation targets), compiled.
 *
 * The rotation Q minimising sum_k w_k |Q v_k - u_k|^2 is the unit quaternion maximising
 * q^T N q for Horn's symmetric 4x4 matrix N of the weighted cross-covariance (Davenport's
 * q-method): its principal eigenvector, found here by cyclic Jacobi rotations, which are
 * accurate for any spread of eigenvalues. It is the same rotation as the SVD solution; only
 * the last bits differ. */
#include "fit.h"

#include <math.h>

/* Eigen-decomposition of a symmetric 4x4 matrix (overwritten): eigenvalues on the diagonal,
 * eigenvectors in the columns of vec. */
static void jacobi4(double a[4][4], double vec[4][4]) {
    int p, q, r, sweep;
    for (p = 0; p < 4; ++p)
        for (q = 0; q < 4; ++q) vec[p][q] = p == q ? 1.0 : 0.0;
    for (sweep = 0; sweep < 64; ++sweep) {
        double off = 0.0, diag = 0.0;
        for (p = 0; p < 4; ++p) {
            diag += fabs(a[p][p]);
            for (q = p + 1; q < 4; ++q) off += fabs(a[p][q]);
        }
        if (off <= 1e-300 || off <= 1e-17 * diag) return;
        for (p = 0; p < 4; ++p) {
            for (q = p + 1; q < 4; ++q) {
                double theta, t, c, s, app, aqq, apq;
                if (a[p][q] == 0.0) continue;
                app = a[p][p]; aqq = a[q][q]; apq = a[p][q];
                theta = (aqq - app) / (2.0 * apq);
                t = (theta >= 0.0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                c = 1.0 / sqrt(t * t + 1.0);
                s = t * c;
                for (r = 0; r < 4; ++r) {
                    double arp, arq;
                    if (r == p || r == q) continue;
                    arp = a[r][p]; arq = a[r][q];
                    a[r][p] = a[p][r] = c * arp - s * arq;
                    a[r][q] = a[q][r] = s * arp + c * arq;
                }
                a[p][p] = app - t * apq;
                a[q][q] = aqq + t * apq;
                a[p][q] = a[q][p] = 0.0;
                for (r = 0; r < 4; ++r) {
                    const double vp = vec[r][p], vq = vec[r][q];
                    vec[r][p] = c * vp - s * vq;
                    vec[r][q] = s * vp + c * vq;
                }
            }
        }
    }
}

int32_t mcf_wahba(int64_t frames, int32_t count, const double* v, const double* u, const double* w,
                  const double* hint, double* out) {
    int64_t f;
    if (frames < 0 || count < 1 || !v || !u || !w || !hint || !out) return -1;
    for (f = 0; f < frames; ++f) {
        /* S[a][b] = sum_k w_k v_k[a] u_k[b]: source v, target u. */
        double S[3][3] = {{0.0}}, N[4][4], vec[4][4], q[4], norm, dot;
        int k, a, b, best;
        const double* vf = v + f * count * 3;
        const double* uf = u + f * count * 3;
        for (k = 0; k < count; ++k)
            for (a = 0; a < 3; ++a)
                for (b = 0; b < 3; ++b) S[a][b] += w[k] * vf[3 * k + a] * uf[3 * k + b];
        /* Horn's N in the order w x y z. */
        N[0][0] = S[0][0] + S[1][1] + S[2][2];
        N[0][1] = N[1][0] = S[1][2] - S[2][1];
        N[0][2] = N[2][0] = S[2][0] - S[0][2];
        N[0][3] = N[3][0] = S[0][1] - S[1][0];
        N[1][1] = S[0][0] - S[1][1] - S[2][2];
        N[1][2] = N[2][1] = S[0][1] + S[1][0];
        N[1][3] = N[3][1] = S[2][0] + S[0][2];
        N[2][2] = -S[0][0] + S[1][1] - S[2][2];
        N[2][3] = N[3][2] = S[1][2] + S[2][1];
        N[3][3] = -S[0][0] - S[1][1] + S[2][2];
        jacobi4(N, vec);
        best = 0;
        for (a = 1; a < 4; ++a)
            if (N[a][a] > N[best][best]) best = a;
        q[0] = vec[1][best]; q[1] = vec[2][best]; q[2] = vec[3][best]; q[3] = vec[0][best];
        norm = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
        dot = q[0] * hint[4 * f] + q[1] * hint[4 * f + 1] + q[2] * hint[4 * f + 2] + q[3] * hint[4 * f + 3];
        if (dot < 0.0) norm = -norm;
        for (a = 0; a < 4; ++a) out[4 * f + a] = q[a] / norm;
    }
    return 0;
}
