/* wcs_prj.c -- test helper: WCSLIB's cube projections (TSC, CSC, QSC) with
 * r0 = 180/pi, vectorised, for tests/test_projection.py (loaded via ctypes).
 * code: 0 tsc, 1 csc, 2 qsc.  Returns WCSLIB's status (0 = all points ok). */
#include <wcslib/prj.h>

static int plodtest__setup(struct prjprm *prj, int code)
{
    prjini(prj);
    prj->r0 = 0.0; /* WCSLIB then uses 180/pi: x, y in degrees */
    switch (code) {
    case 0: return tscset(prj);
    case 1: return cscset(prj);
    case 2: return qscset(prj);
    default: return -1;
    }
}

int plodtest_s2x(int code, int n, const double *phi, const double *theta,
                 double *x, double *y, int *stat)
{
    struct prjprm prj;
    if (plodtest__setup(&prj, code))
        return -1;
    return prj.prjs2x(&prj, n, 0, 1, 1, phi, theta, x, y, stat);
}

int plodtest_x2s(int code, int n, const double *x, const double *y,
                 double *phi, double *theta, int *stat)
{
    struct prjprm prj;
    if (plodtest__setup(&prj, code))
        return -1;
    return prj.prjx2s(&prj, n, 0, 1, 1, x, y, phi, theta, stat);
}
