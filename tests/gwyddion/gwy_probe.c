/* Gwyddion as an independent reader and writer of surface files, for the tests of
 * include/wavebrdf/surface_file.h: loads IN with Gwyddion's own file modules and prints what it
 * found (size, physical size in m, height unit, statistics, masked points and a few values), and,
 * given OUT, saves the loaded data with Gwyddion's exporter for OUT's extension.
 * Usage: gwy_probe IN [OUT]   (exit 0 on success) */
#include <stdio.h>
#include <libgwyddion/gwyddion.h>
#include <libprocess/gwyprocess.h>
#include <libgwymodule/gwymodule.h>
#include <libgwydgets/gwydgets.h>
#include <app/gwyapp.h>

int main(int argc, char **argv) {
    if (argc < 2) {
        fprintf(stderr, "usage: gwy_probe IN [OUT]\n");
        return 2;
    }
    gwy_app_init_nongui(NULL);
    gwy_app_data_browser_set_gui_enabled(FALSE);
    GError *error = NULL;
    GwyContainer *data = gwy_file_load(argv[1], GWY_RUN_NONINTERACTIVE, &error);
    if (!data) {
        fprintf(stderr, "gwy_probe: cannot load %s: %s\n", argv[1], error ? error->message : "unknown");
        return 1;
    }
    gint *ids = gwy_app_data_browser_get_data_ids(data);
    if (!ids || ids[0] < 0) {
        fprintf(stderr, "gwy_probe: %s holds no channel\n", argv[1]);
        return 1;
    }
    GwyDataField *field = GWY_DATA_FIELD(gwy_container_get_object(data, gwy_app_get_data_key_for_id(ids[0])));
    GwyDataField *mask = NULL;
    gwy_container_gis_object(data, gwy_app_get_mask_key_for_id(ids[0]), (GObject **)&mask);
    const gint xres = gwy_data_field_get_xres(field), yres = gwy_data_field_get_yres(field);
    gchar *zunit = gwy_si_unit_get_string(gwy_data_field_get_si_unit_z(field), GWY_SI_UNIT_FORMAT_PLAIN);
    gchar *xyunit = gwy_si_unit_get_string(gwy_data_field_get_si_unit_xy(field), GWY_SI_UNIT_FORMAT_PLAIN);
    gint masked = 0;
    if (mask) {
        const gdouble *m = gwy_data_field_get_data_const(mask);
        for (gint i = 0; i < xres * yres; i++) masked += m[i] > 0.5;
    }
    const gdouble *d = gwy_data_field_get_data_const(field);
    printf("xres %d\nyres %d\nxreal %.17g\nyreal %.17g\nxyunit %s\nzunit %s\n", xres, yres,
           gwy_data_field_get_xreal(field), gwy_data_field_get_yreal(field), xyunit, zunit);
    printf("masked %d\n", masked);
    printf("min %.17g\nmax %.17g\navg %.17g\nrms %.17g\n", gwy_data_field_get_min(field), gwy_data_field_get_max(field),
           gwy_data_field_get_avg(field), gwy_data_field_get_rms(field));
    /* Corners and the point after the first row: where the layout and the orientation show. */
    printf("z00 %.17g\nz01 %.17g\nz10 %.17g\nzlast %.17g\n", d[0], d[1], d[xres], d[xres * yres - 1]);
    if (argc > 2) {
        /* Exporters save the data browser's current channel. */
        gwy_app_data_browser_add(data);
        gwy_app_data_browser_select_data_field(data, ids[0]);
        if (!gwy_file_save(data, argv[2], GWY_RUN_NONINTERACTIVE, &error)) {
            fprintf(stderr, "gwy_probe: cannot save %s: %s\n", argv[2], error ? error->message : "unknown");
            return 1;
        }
    }
    return 0;
}
