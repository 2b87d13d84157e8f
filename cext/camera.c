/* camera.c -- the camera in Blender's conventions.
 *
 * matrix_world columns are the camera's local axes in planet space (x
 * right, y up, z backwards) and its position; scale is removed (Blender
 * ignores object scale for the view).  The view window at unit depth
 * follows Blender's sensor fit: AUTO fits the sensor width to the larger
 * of the two (pixel-aspect-corrected) image sides; shift is a fraction of
 * that fitted side.  The visibility tests that use it are in bound.c.
 */
#include "plod_camera.h"

#include <math.h>
#include <string.h>

void plod_camera_desc_default(plod_camera_desc *desc)
{
    memset(desc, 0, sizeof *desc);
    for (int i = 0; i < 4; i++)
        desc->matrix_world[i * 5] = 1.0;
    desc->orthographic = 0;
    desc->lens = 50.0;
    desc->sensor_width = 36.0;
    desc->sensor_height = 24.0;
    desc->sensor_fit = PLOD_SENSOR_AUTO;
    desc->ortho_scale = 7.0;
    desc->clip_start = 0.1;
    desc->clip_end = 1000.0;
    desc->resolution_x = 1920;
    desc->resolution_y = 1080;
    desc->pixel_aspect_x = 1.0;
    desc->pixel_aspect_y = 1.0;
}

static void plod__set_plane(double plane[4], const plod_camera *cam, double lx,
                            double ly, double lz, double ld)
{
    double n[3];
    for (int i = 0; i < 3; i++)
        n[i] = cam->right[i] * lx + cam->up[i] * ly - cam->forward[i] * lz;
    double len = plod_norm3(n);
    for (int i = 0; i < 3; i++)
        plane[i] = n[i] / len;
    plane[3] = (ld - plod_dot3(n, cam->position)) / len;
}

plod_status plod_camera_init(plod_camera *camera, const plod_camera_desc *desc)
{
    if (!camera || !desc)
        return PLOD_ERR_NULL;
    const plod_camera_desc *d = desc;
    for (int i = 0; i < 16; i++)
        if (!isfinite(d->matrix_world[i]))
            return PLOD_ERR_BAD_CAMERA;
    double scalars[] = {d->lens, d->sensor_width, d->sensor_height, d->ortho_scale,
                        d->shift_x, d->shift_y, d->clip_start, d->clip_end,
                        d->pixel_aspect_x, d->pixel_aspect_y};
    for (size_t i = 0; i < sizeof scalars / sizeof scalars[0]; i++)
        if (!isfinite(scalars[i]))
            return PLOD_ERR_BAD_CAMERA;
    if (d->resolution_x <= 0 || d->resolution_y <= 0 || d->pixel_aspect_x <= 0 ||
        d->pixel_aspect_y <= 0 || d->clip_start <= 0 || d->clip_end <= d->clip_start)
        return PLOD_ERR_BAD_CAMERA;
    if (d->orthographic ? !(d->ortho_scale > 0)
                        : !(d->lens > 0 && d->sensor_width > 0 && d->sensor_height > 0))
        return PLOD_ERR_BAD_CAMERA;
    if ((unsigned)d->sensor_fit > PLOD_SENSOR_VERTICAL)
        return PLOD_ERR_BAD_CAMERA;

    const double *m = d->matrix_world;
    if (m[12] != 0.0 || m[13] != 0.0 || m[14] != 0.0 || m[15] != 1.0)
        return PLOD_ERR_BAD_CAMERA; /* projective matrices are not cameras */
    double x[3] = {m[0], m[4], m[8]}, y[3] = {m[1], m[5], m[9]},
           z[3] = {m[2], m[6], m[10]};
    double sx = plod_norm3(x), sy = plod_norm3(y), sz = plod_norm3(z);
    double cross[3] = {x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2],
                       x[0] * y[1] - x[1] * y[0]};
    double det = plod_dot3(cross, z);
    if (!(sx > 0 && sy > 0 && sz > 0) || !(fabs(det) > 1e-9 * sx * sy * sz))
        return PLOD_ERR_BAD_CAMERA;

    memset(camera, 0, sizeof *camera);
    camera->desc = *d;
    camera->position[0] = m[3];
    camera->position[1] = m[7];
    camera->position[2] = m[11];
    /* Gram-Schmidt keeps the view direction exact and squares the rest. */
    double f[3] = {-z[0] / sz, -z[1] / sz, -z[2] / sz};
    double yd = plod_dot3(y, f);
    double u[3] = {y[0] - yd * f[0], y[1] - yd * f[1], y[2] - yd * f[2]};
    double ul = plod_norm3(u);
    if (!(ul > 1e-12 * sy))
        return PLOD_ERR_BAD_CAMERA;
    for (int i = 0; i < 3; i++) {
        camera->forward[i] = f[i];
        camera->up[i] = u[i] / ul;
    }
    /* right = up x back = forward x up */
    camera->right[0] = f[1] * camera->up[2] - f[2] * camera->up[1];
    camera->right[1] = f[2] * camera->up[0] - f[0] * camera->up[2];
    camera->right[2] = f[0] * camera->up[1] - f[1] * camera->up[0];

    double aspect_x = d->resolution_x * d->pixel_aspect_x;
    double aspect_y = d->resolution_y * d->pixel_aspect_y;
    int horizontal = d->sensor_fit == PLOD_SENSOR_HORIZONTAL ||
                     (d->sensor_fit == PLOD_SENSOR_AUTO && aspect_x >= aspect_y);
    double fit_half; /* half the fitted side, at unit depth or in metres */
    if (d->orthographic)
        fit_half = d->ortho_scale * 0.5;
    else if (d->sensor_fit == PLOD_SENSOR_VERTICAL)
        fit_half = d->sensor_height * 0.5 / d->lens;
    else
        fit_half = d->sensor_width * 0.5 / d->lens;
    double half_x = horizontal ? fit_half : fit_half * aspect_x / aspect_y;
    double half_y = horizontal ? fit_half * aspect_y / aspect_x : fit_half;
    double off_x = 2.0 * fit_half * d->shift_x, off_y = 2.0 * fit_half * d->shift_y;
    camera->tan_left = off_x - half_x;
    camera->tan_right = off_x + half_x;
    camera->tan_bottom = off_y - half_y;
    camera->tan_top = off_y + half_y;
    double ppx = d->resolution_x / (2.0 * half_x);
    double ppy = d->resolution_y / (2.0 * half_y);
    double pp = ppx > ppy ? ppx : ppy;
    if (!isfinite(pp) || !(pp > 0))
        return PLOD_ERR_BAD_CAMERA;
    if (d->orthographic) {
        camera->pixels_per_metre = pp;
    } else {
        double tx = fmax(fabs(camera->tan_left), fabs(camera->tan_right));
        double ty = fmax(fabs(camera->tan_bottom), fabs(camera->tan_top));
        /* a length seen at the frame corner projects up to 1/cos^2 larger */
        camera->pixels_per_radian = pp * (1.0 + tx * tx + ty * ty);
    }

    double n = d->clip_start, fa = d->clip_end;
    if (d->orthographic) {
        plod__set_plane(camera->planes[0], camera, 1, 0, 0, -camera->tan_left);
        plod__set_plane(camera->planes[1], camera, -1, 0, 0, camera->tan_right);
        plod__set_plane(camera->planes[2], camera, 0, 1, 0, -camera->tan_bottom);
        plod__set_plane(camera->planes[3], camera, 0, -1, 0, camera->tan_top);
    } else {
        /* local x >= tan_left * depth with depth = -z */
        plod__set_plane(camera->planes[0], camera, 1, 0, camera->tan_left, 0);
        plod__set_plane(camera->planes[1], camera, -1, 0, -camera->tan_right, 0);
        plod__set_plane(camera->planes[2], camera, 0, 1, camera->tan_bottom, 0);
        plod__set_plane(camera->planes[3], camera, 0, -1, -camera->tan_top, 0);
    }
    plod__set_plane(camera->planes[4], camera, 0, 0, -1, -n);
    plod__set_plane(camera->planes[5], camera, 0, 0, 1, fa);
    for (int i = 0; i < 6; i++)
        for (int k = 0; k < 4; k++)
            if (!isfinite(camera->planes[i][k]))
                return PLOD_ERR_BAD_CAMERA;
    return PLOD_OK;
}

int plod_camera_contains(const plod_camera *camera, const double point[3])
{
    for (int i = 0; i < 6; i++)
        if (plod_dot3(camera->planes[i], point) + camera->planes[i][3] < 0.0)
            return 0;
    return 1;
}
