// LEGACY, for the path integrator's marks only: the statements renderer/shader_source.py puts at
// the "//@TRIANGLES <name>" and "//@SHAPES <name>" lines inside lighting.glsl's path_main (the
// only marks left; every other chunk is whole and switched by FEATURE_* defines). Section
// "triangles.<name>" fills "//@TRIANGLES <name>" where FEATURE_TRIANGLES is 1, "shapes.<name>"
// fills "//@SHAPES <name>" where FEATURE_SHAPES is 1; elsewhere the mark line is removed. These
// go once path_main tests FEATURE_TRIANGLES and FEATURE_SHAPES itself. A section runs from its
// "//@SECTION <name>" line to the next one.

//@SECTION triangles.path_ng
            ng = s.ng;   // emission and the side a path meets: by the geometric normal

//@SECTION triangles.path_emit_mis
                // An emitting triangle that next-event estimation samples (all are, when any is).
                if (prev_pdf > 0.0 && h.id >= u_tri_base && u_num_emit_tris > 0) {
                    float cos_light = -dot(d, ng);
                    float p_l = h.t * h.t / (u_emit_tri_area * max(cos_light, 1e-12));
                    w = prev_pdf * prev_pdf / (prev_pdf * prev_pdf + p_l * p_l);
                }

//@SECTION shapes.path_emit_mis
                // An emitting shape's surface that next-event estimation samples (all are, when any is):
                // its pdf in solid angle is the triangles' form over the shapes' total area.
                if (h.id >= u_shape_base) {
                    w = 1.0;
#ifndef NO_SHAPE_LIGHTS
                    if (prev_pdf > 0.0 && u_num_emit_patches > 0) {
                        float p_l = h.t * h.t / (u_emit_patch_area * max(-dot(d, ng), 1e-12));
                        w = prev_pdf * prev_pdf / (prev_pdf * prev_pdf + p_l * p_l);
                    }
#endif
                }
