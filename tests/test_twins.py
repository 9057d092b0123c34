"""Every @njit kernel in reflectcli is held to a slow twin (tests/naive.py) by a test.

KERNELS maps each kernel ("module path:function") to the tests that compare it with its
twin; a private helper compiled into its caller is listed with the caller's tests and the
caller it is reached through. The test fails on a kernel missing from the map, on an entry
for a kernel that no longer exists, and on a named test that does not exist."""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

R = "tests/raster/test_rasterize.py::"
W = "tests/maps/test_warp_splat.py::"
E = "tests/trace/test_embree_bruteforce.py::"
SR = "tests/twins/test_shading_raster_twins.py::"
T = "tests/twins/test_trace_twins.py::"
M = "tests/twins/test_maps_twins.py::"
V = "tests/twins/test_virtual_twins.py::"
VR = "tests/twins/test_virtual_refine_twins.py::"
VE = "tests/twins/test_virtual_explosion_twins.py::"
VS = "tests/twins/test_virtual_partsetup_twins.py::"
D = "tests/maps/test_distance_search.py::"

RASTER = [R + "test_matches_reference_on_random_scenes",
          R + "test_fill_matches_the_exact_pixel_by_pixel_twin",
          R + "test_near_plane_clipping_matches_ray_casting",
          SR + "test_rasterizer_with_mask_and_depth_floor_matches_twin",
          SR + "test_rasterizer_culling_and_skip_match_twin"]
CLIP = [R + "test_near_plane_clipping_matches_ray_casting"]
RECOVER = [SR + "test_shade_pass_recovering_barycentrics_matches_twin",
           R + "test_matches_reference_on_random_scenes"]
SPLAT = [W + "test_splat_matches_the_reference",
         M + "test_splat_both_modes_match_sequential_twin"]
PIXELS = [W + "test_pixel_splat_matches_the_reference",
          M + "test_pixel_splat_both_modes_match_sequential_twin",
          M + "test_splat_projecting_inside_matches_project_then_splat",
          W + "test_pixel_splat_matches_at_thread_counts_with_a_partly_full_stencil"]
SPREAD = [W + "test_spread_matches_the_reference"]
ANALYTIC = [E + "test_analytic_matches_closed_forms"]
SPHERE_METHOD = [V + "test_sphere_virtual_vertices_match_twin",
                 V + "test_cylinder_virtual_vertices_match_twin",
                 V + "test_sphere_blocks_do_not_change_answers",
                 V + "test_spheres_together_give_each_sphere_s_bytes",
                 V + "test_sphere_blocks_give_the_one_at_a_time_search_s_bytes"]
PROFILE = [V + "test_profile_virtual_vertices_match_twin"]
REFINE = [VR + "test_screen_refinement_matches_twin",
          VR + "test_refinement_walks_match_twin",
          VR + "test_refinement_lanes_match_walks_one_at_a_time",
          VR + "test_refinement_skips_only_retries_that_cannot_matter"]
FILL = [VE + "test_fill_kernels_match_twin"]
PASSES = [SR + "test_rasterize_passes_match_twin",
          SR + "test_rasterize_passes_are_the_passes_one_at_a_time"]
SEARCH = [D + "test_search_matches_naive_twin", D + "test_box_room_hit_is_exact_on_planes"]
LOOKUP = [VE + "test_explosion_lookup_matches_twin"]
IDS_AT = [VE + "test_ids_at_marked_texels_match_the_fill_twins"]
HOLES = [VE + "test_hole_fill_matches_the_whole_layer_s_nearest_fill",
         VE + "test_hole_fill_of_lattice_triangles_matches_the_fill_twins",
         VE + "test_hole_fill_takes_a_tie_at_the_corner_of_a_triangle_s_texels",
         VE + "test_hole_fill_keeps_a_tie_at_the_bound_of_its_ring_of_cells",
         VE + "test_hole_fill_rings_start_at_the_hole_s_own_cell",
         VE + "test_hole_fill_of_random_small_layers_matches_the_fill_twins",
         VE + "test_maps_built_for_their_lookups_match_whole_maps_there"]
# a reflector's parts stage by stage, against each part's own call (its stages twin-tested)
PARTS = [V + "test_parts_together_give_each_part_s_answers"]
PART_PASSES = [V + "test_part_passes_together_give_the_frame_part_by_part"]
SPHERES_TOGETHER = [V + "test_spheres_drawn_together_give_the_frame_sphere_by_sphere"]
S = "tests/techniques/test_ssr.py::"
P = "tests/techniques/test_ppr.py::"
HIZ = [S + "test_hiz_equals_pixel_walk_on_random_buffers",
       S + "test_hiz_equals_pixel_walk_on_frames"]
DDA = [S + "test_dda_equals_listing"]
RESOLVE = [S + "test_resolve_and_confidence_match_twins"]
WAVE = [T + "test_wave_matches_twin", T + "test_primary_wave_matches_twin"]
# whole frames, every wave of a segment in one call against one wave a call (the embreex
# fallback), and any thread count
FRAMES = ["tests/trace/test_tracer_frames.py::test_embreex_fallback_gives_the_same_frames",
          "tests/trace/test_tracer_frames.py::test_frames_do_not_depend_on_the_thread_count"]

# kernel -> (tests comparing it with its twin, the kernel it is reached through or None)
KERNELS: dict[str, tuple[list[str], str | None]] = {
    "shading.py:_texel": ([SR + "test_material_albedo_matches_twin"], "material_albedo"),
    "shading.py:material_albedo": ([SR + "test_material_albedo_matches_twin"], None),
    "shading.py:surface_color": ([SR + "test_surface_color_matches_twin"], None),
    "trace/rays.py:_primary_rays": ([SR + "test_primary_rays_match_pixel_directions"], None),
    "raster/bounds.py:run_bounds": ([SR + "test_run_bounds_match_twin"], None),
    "trace/rays.py:rows_of_rays": ([SR + "test_primary_rays_match_pixel_directions",
                                    T + "test_primary_wave_matches_twin"], "_primary_rays"),
    "trace/rays.py:_row": ([SR + "test_primary_rays_match_pixel_directions",
                            T + "test_primary_wave_matches_twin"], "rows_of_rays"),
    "prefetch.py:prefetch": (RECOVER + [SR + "test_prefetch_changes_no_value"], "_shade_row"),
    "prefetch.py:prefetch_write": ([SR + "test_prefetch_changes_no_value"] + PIXELS,
                                   "_ready_rows"),
    "raster/shade.py:_shade": ([SR + "test_shade_pass_matches_twin"], None),
    "raster/shade.py:_shade_stencil": ([SR + "test_shade_pass_matches_twin"], None),
    # held to _resolve then _shade_stencil, each held to its twin
    "raster/shade.py:_shade_stencil_resolving": (
        [SR + "test_shading_that_merges_the_threads_buffers_is_merge_then_shade"],
        "shade_buffers"),
    "raster/shade.py:_shade_pixel": ([SR + "test_shade_pass_matches_twin"], "_shade"),
    "raster/shade.py:_object_pixel": ([SR + "test_shade_pass_matches_twin"], "_shade_pixel"),
    "raster/shade.py:_shade_row": (RECOVER, "_shade"),
    "raster/shade.py:_run_setup": (RECOVER, "_shade_row"),
    "raster/shade.py:_run_weights": (RECOVER, "_run_setup"),
    "raster/shade.py:_run_setup_albedo": (RECOVER, "_shade_row"),
    "raster/shade.py:_light_row": (RECOVER, "_shade_row"),
    "raster/shade.py:add_reflection": ([SR + "test_add_reflection_matches_twin"], None),
    "raster/rasterize/draw.py:_draw": (RASTER, "rasterize"),
    "raster/rasterize/fixed.py:_snap": (RASTER, "_draw"),
    "raster/rasterize/clip.py:screen_from_ndc": (RASTER, "_run_setup"),
    "raster/rasterize/clip.py:_clip_xyzw": (RASTER, "_draw"),
    "raster/rasterize/clip.py:_outside": (RASTER, "_box_misses"),
    "raster/rasterize/setup.py:_run_setup": (RASTER, "_draw"),
    # the one-triangle entry (_fill_at into a box of its own) the exact twin drives
    "raster/rasterize/rows.py:_fill": ([R + "test_fill_matches_the_exact_pixel_by_pixel_twin"],
                                       None),
    "raster/rasterize/setup.py:_setup": (RASTER + PASSES, "_fill_at"),
    "raster/rasterize/setup.py:_facing": (RASTER + PASSES, "_setup"),
    "raster/rasterize/setup.py:_centers": (RASTER + PASSES, "_setup"),
    "raster/rasterize/setup.py:_mul": (RASTER + PASSES, "_setup"),
    "raster/rasterize/setup.py:_real": (RASTER + PASSES, "_setup"),
    "raster/rasterize/setup.py:_store_setup": (RASTER + PASSES, "_run_setup"),
    "raster/rasterize/setup.py:triangle_cull": (
        RASTER + ["tests/raster/test_rasterize.py::"
                  "test_flagged_back_faces_are_dropped_as_if_skipped"], "_run_setup"),
    "raster/rasterize/draw.py:_fill_listed": (RASTER + PASSES, "_draw"),
    "raster/rasterize/rows.py:_rows": (RASTER + PASSES, "_fill_listed"),
    "raster/rasterize/rows.py:_quad": (RASTER + PASSES, "_fill_listed"),
    "raster/rasterize/rows.py:_narrow": (RASTER, "_narrow_at"),
    "raster/rasterize/draw.py:_narrow_at": (RASTER, "_fill_listed"),
    "raster/rasterize/rows.py:_pixel": (RASTER + PASSES, "_quad"),
    "raster/rasterize/rows.py:_fill_at": (CLIP + PASSES, "_draw_clipped"),
    "raster/rasterize/passes.py:_draw_passes": (PASSES, "rasterize_passes"),
    "raster/rasterize/gather.py:gather_triangle": (
        [V + "test_gather_corners_match_twin"] + PASSES, "gather_corners"),
    "raster/rasterize/draw.py:_draw_clipped": (CLIP + PASSES, "_draw"),
    "raster/rasterize/clip.py:_clip_polygon": (CLIP, "_draw_clipped"),
    "raster/rasterize/resolve.py:_resolve": (
        RASTER + [R + "test_clear_outside_false_keeps_pixels_outside_the_box"], "rasterize"),
    "raster/rasterize/resolve.py:resolve_row": (
        RASTER + [SR + "test_shading_that_merges_the_threads_buffers_is_merge_then_shade"],
        "_resolve"),
    "raster/rasterize/stencil.py:stencil_box": ([R + "test_stencil_box_matches_twin"], None),
    "raster/rasterize/clip.py:_box_misses": (
        [R + "test_skipping_chunks_by_their_boxes_changes_nothing"], "_draw"),
    "raster/rasterize/barycentrics.py:recover_barycentrics": (RECOVER, None),
    "raster/rasterize/barycentrics.py:clip_corners": (RECOVER, "recover_barycentrics"),
    "raster/rasterize/barycentrics.py:barycentrics_at": (RECOVER, "recover_barycentrics"),
    "raster/rasterize/barycentrics.py:_barycentrics": (RECOVER, "RasterBuffers.b1"),
    "maps/warp/payload.py:_gather4": ([W + "test_gather_and_fill_blend_match_twins"],
                                      "gather_colors"),
    "maps/warp/fill.py:fill_blend": ([W + "test_gather_and_fill_blend_match_twins"], None),
    "maps/warp/fill.py:_fill_row": ([W + "test_gather_and_fill_blend_match_twins"],
                                    "fill_blend"),
    "trace/embree.py:_intersect": ([E + "test_embree_matches_moller_trumbore",
                                    E + "test_embree_hits_are_common_in_the_property_test",
                                    E + "test_embree_kernel_equals_embreex_bit_for_bit",
                                    E + "test_embreex_fallback_gives_the_same_hits"],
                                   "TriangleScene.intersect"),
    "trace/embree.py:intersect_range": ([E + "test_embree_kernel_equals_embreex_bit_for_bit"]
                                        + WAVE, "_intersect"),
    "trace/embree.py:packet_buffer": ([E + "test_embree_kernel_equals_embreex_bit_for_bit"]
                                      + WAVE, "_intersect"),
    "trace/analytic.py:_sphere": (ANALYTIC, "_intersect"),
    "trace/analytic.py:_cylinder": (ANALYTIC, "_intersect"),
    "trace/analytic.py:_inner": (ANALYTIC, "_quad_run"),
    "trace/analytic.py:_quad_run": (ANALYTIC + WAVE, "_mirror_run"),
    "trace/analytic.py:_mirror_run": (ANALYTIC + WAVE, "intersect_range"),
    "trace/analytic.py:_start": (ANALYTIC + WAVE, "intersect_range"),
    "trace/analytic.py:_finish": (ANALYTIC + WAVE, "intersect_range"),
    "trace/analytic.py:_intersect": (
        ANALYTIC + [E + "test_analytic_property_cases_are_mostly_clear"], "intersect_analytic"),
    "trace/analytic.py:intersect_range": (ANALYTIC + WAVE, "_wave"),
    "trace/analytic.py:intersect_rows": (
        WAVE + ["tests/trace/test_screen_boxes.py::test_every_mirror_hit_lies_in_its_box"],
        "_wave"),
    "trace/resolve.py:_pick": ([T + "test_pick_matches_twin_on_ties_and_misses",
                               T + "test_resolve_matches_twin"], None),
    "trace/resolve.py:resolve_range": ([T + "test_resolve_matches_twin"] + WAVE, None),
    "trace/resolve.py:planar_units": ([T + "test_planar_units_match_twin",
                                       T + "test_resolve_matches_twin"] + WAVE, None),
    "trace/wave.py:trace_segments": (WAVE + FRAMES, None),
    "trace/wave.py:_segment": (WAVE + FRAMES, "trace_segments"),
    "parallel.py:claim": (WAVE + FRAMES + [R + "test_deterministic_across_thread_counts",
                                           R + "test_claim_hands_out_each_piece_once"],
                          "trace_segments"),
    "parallel.py:claim_rows": ([R + "test_claim_rows_hands_out_each_row_once"] + SEARCH,
                               "_search_pixels"),
    # the counter every claim loop starts from: held by the same tests
    "parallel.py:counter": (WAVE + FRAMES + [R + "test_deterministic_across_thread_counts",
                                             R + "test_claim_hands_out_each_piece_once"],
                            "trace_segments"),
    "trace/wave.py:_wave": (WAVE + FRAMES, "_segment"),
    "trace/wave.py:_misses": (WAVE, "_wave"),
    "trace/wave.py:_rows2": (WAVE + FRAMES, "trace_segments"),
    "trace/wave.py:_rows4": (WAVE + FRAMES, "trace_segments"),
    "trace/wave.py:_rows_hits": (WAVE + FRAMES, "trace_segments"),
    "trace/wave.py:_rows_analytic": (WAVE + FRAMES, "trace_segments"),
    "trace/resolve.py:_add": ([T + "test_resolve_matches_twin"], "resolve_range"),
    "trace/resolve.py:_ray": ([T + "test_resolve_matches_twin"], "resolve_range"),
    "maps/cube.py:cube_face_coords": ([M + "test_cube_lookup_matches_twin"], None),
    "maps/cube.py:cube_sample": ([M + "test_cube_lookup_matches_twin"], None),
    "maps/cube.py:image_sample": ([M + "test_image_sample_matches_twin"], None),
    "maps/cube.py:_bilinear": ([M + "test_image_sample_matches_twin"], "image_sample"),
    "maps/sphere.py:_sphere_from_cube": ([M + "test_sphere_from_cube_matches_twin"], None),
    "maps/sphere.py:sphere_coords": ([M + "test_sphere_lookup_matches_twin"], None),
    "maps/sphere.py:sphere_sample": ([M + "test_sphere_lookup_matches_twin"], None),
    "maps/lookup.py:box_exit": ([M + "test_box_exit_matches_twin"], None),
    "maps/lookup.py:_add": ([M + "test_envmap_lookup_matches_twin"], None),
    "maps/lookup.py:_add_row": ([M + "test_envmap_lookup_matches_twin"], "_add"),
    "maps/surface.py:_intersect": ([M + "test_surface_reconstruction_matches_twin"], None),
    "maps/warp/projection.py:_project": ([M + "test_warp_projection_matches_twin"], "project_map"),
    "maps/warp/projection.py:_project_row": ([M + "test_warp_projection_matches_twin",
                                   M + "test_splat_projecting_inside_matches_project_then_splat"],
                                  "_project"),
    "maps/warp/projection.py:_row_reach": (
        [M + "test_row_reach_bounds_the_twin_projection",
         M + "test_splat_projecting_inside_matches_project_then_splat"], "_splat_pixels"),
    "maps/warp/squares.py:_adaptive": ([M + "test_adaptive_radii_match_twin"], "splat_radii"),
    "maps/warp/squares.py:_splat": (SPLAT, "splat"),
    "maps/warp/squares.py:_write": (SPLAT, "_splat"),
    "maps/warp/pixels.py:_splat_pixels": (PIXELS, "splat_pixels"),
    "maps/warp/pixels.py:_scatter_width": (
        PIXELS + [W + "test_payload_rows_follow_the_ids_over_several_maps"], "_splat_pixels"),
    "maps/warp/pixels.py:_scatter_run": (
        PIXELS + [W + "test_payload_rows_follow_the_ids_over_several_maps"], "_scatter_width"),
    "maps/warp/pixels.py:_ready_rows": (PIXELS, "_splat_pixels"),
    "maps/warp/pixels.py:_clear_rows": (PIXELS, "_ready_rows"),
    "maps/warp/pixels.py:_scatter_loop": (
        PIXELS + [W + "test_payload_rows_follow_the_ids_over_several_maps"], "_scatter_run"),
    "maps/warp/pixels.py:_all_set": (
        [W + "test_pixel_splat_matches_at_thread_counts_with_a_partly_full_stencil",
         W + "test_pixel_splat_matches_the_reference"], "_splat_pixels"),
    "maps/warp/pixels.py:_reaches": (
        PIXELS + [M + "test_row_reach_bounds_the_twin_projection"], "_splat_pixels"),
    "maps/warp/spreading.py:_spread": (SPREAD, "spread"),
    "maps/warp/spreading.py:_spread_band": (SPREAD, "_spread"),
    "maps/warp/spreading.py:_key_row": (SPREAD, "_spread_band"),
    "maps/warp/spreading.py:_own_depths": (SPREAD, "_spread_band"),
    "maps/warp/spreading.py:_min_into": (SPREAD, "_spread_band"),
    "maps/warp/spreading.py:_spread_pick": (SPREAD, "_spread_band"),
    "maps/warp/spreading.py:_spread_band_rings": (SPREAD, "_spread"),
    "maps/warp/spreading.py:_spread_pick_ring": (SPREAD, "_spread_band_rings"),
    "maps/warp/spreading.py:_nearer_ring": (SPREAD, "_spread_band_rings"),
    "maps/warp/payload.py:_copy_row": ([W + "test_payload_rows_follow_the_ids_over_several_maps",
                                        SPREAD[0]], "_copy_zexel_rows"),
    "maps/warp/payload.py:_copy_zexel_rows": (SPREAD, "_spread_band"),
    "virtual/circle.py:_circle_law": (SPHERE_METHOD, "_newton_step"),
    "virtual/circle.py:_circle_start": (SPHERE_METHOD, "_block"),
    "virtual/circle.py:_newton_step": (SPHERE_METHOD, "_block"),
    "virtual/circle.py:_normal": (SPHERE_METHOD, "_block"),
    "virtual/circle.py:_circle_newton": (SPHERE_METHOD, "_block"),
    "virtual/circle.py:_circle_reflection": (SPHERE_METHOD, "_block"),
    "virtual/circle.py:_block": (SPHERE_METHOD, "_blocks"),
    "virtual/circle.py:_blocks": (SPHERE_METHOD, "sphere/cylinder_virtual_vertices"),
    "virtual/direct.py:_profile_at": (PROFILE, "_law"),
    "virtual/direct.py:_law": (PROFILE, "_profile_one"),
    "virtual/direct.py:_profile_many": (PROFILE, "profile_virtual_vertices"),
    "virtual/direct.py:_profile_one": (PROFILE, "_profile_many"),
    "virtual/compose.py:mirror_boxes": ([V + "test_mirror_boxes_match_twin"], None),
    # render_primary's kernels and mirror_boxes in one region, held to them
    "virtual/primary.py:_primary_rows": ([V + "test_primary_and_boxes_match_render_primary"],
                                         "primary_and_boxes"),
    "virtual/compose.py:part_stencil": ([V + "test_part_stencil_matches_twin"], None),
    "virtual/compose.py:gather_corners": ([V + "test_gather_corners_match_twin"], None),
    "virtual/compose.py:fill_cracks": ([V + "test_fill_cracks_match_twin"], None),
    "virtual/compose.py:pass_labels": ([V + "test_pass_labels_match_twin"], None),
    "virtual/compose.py:compose_passes": ([V + "test_compose_passes_match_twin"], None),
    "virtual/compose.py:_compose_row": ([V + "test_compose_passes_match_twin"] + SPHERES_TOGETHER,
                                       "compose_passes"),
    # shade_buffers(pending=...) and compose_passes in one region, held to the passes drawn
    # one at a time
    "virtual/together.py:_shade_compose": (SPHERES_TOGETHER, "draw_spheres"),
    "virtual/compose.py:_same": ([V + "test_compose_passes_match_twin"], "compose_passes"),
    "virtual/compose.py:_covered": ([V + "test_fill_cracks_match_twin"], "fill_cracks"),
    "virtual/compose.py:_fill_crack": (
        [V + "test_fill_cracks_match_twin", V + "test_compose_passes_match_twin"], "fill_cracks"),
    "virtual/refine.py:_ray_at": ([VR + "test_reflector_grid_matches_twin",
                                   V + "test_mirror_rays_match_reflector_grid",
                                   V + "test_reflector_rays_match_reflector_grid"], "_grid"),
    "virtual/refine.py:mirror_rays": ([V + "test_mirror_rays_match_reflector_grid"], None),
    "virtual/refine.py:_grid": ([VR + "test_reflector_grid_matches_twin"], "reflector_grid"),
    # _grid's arithmetic over the rows' spans, barycentrics recovered: held to its bytes
    "virtual/refine.py:_grid_spans": ([V + "test_reflector_rays_match_reflector_grid"],
                                      "reflector_rays"),
    "virtual/refine.py:_grid_row": ([V + "test_reflector_rays_match_reflector_grid"],
                                    "_grid_spans"),
    "virtual/refine.py:_sample_slope": ([VR + "test_grid_sample_matches_twin",
                                         VR + "test_grid_sample_slope_matches_twin"] + REFINE,
                                        None),
    "virtual/refine.py:_walk": (REFINE, None),  # the serial walk, held to refine_walk
    "virtual/refine.py:_refine": (REFINE + PARTS, "refine_virtual"),
    "virtual/refine.py:_step": (REFINE, "_refine"),
    "virtual/refine.py:_walk_end": (REFINE, "_refine"),
    "virtual/refine.py:_begin": (REFINE, "_refine"),
    "virtual/refine.py:_lane_arrays": (REFINE, "_refine"),
    "virtual/refine.py:_walk_lanes": (REFINE, "_refine"),
    "virtual/refine.py:_gather": (REFINE, "_refine"),
    "virtual/refine.py:_advance": (REFINE, "_refine"),
    "virtual/refine.py:_after_steps": (REFINE, "_refine"),
    "virtual/refine.py:_next_point": (REFINE, "_refine"),
    "virtual/refine.py:_take": (REFINE, "_refine"),
    "virtual/refine.py:_finish_all": (REFINE, "_refine"),
    "virtual/tiles.py:_scan": ([VR + "test_tile_scan_matches_twin",
                                VR + "test_tile_scan_with_a_wide_cone_matches_twin"],
                               "PartTiles.scan"),
    "virtual/tiles.py:_scan_tile": ([VR + "test_tile_scan_matches_twin",
                                     VR + "test_tile_scan_with_a_wide_cone_matches_twin"],
                                    "_scan"),
    "virtual/tiles.py:_scan_reached": ([VR + "test_tile_scan_matches_twin",
                                        VR + "test_tile_scan_with_a_wide_cone_matches_twin",
                                        VR + "test_tile_scan_blocks_skip_only_tiles_that_reach_"
                                        "none_of_them"], "PartTiles.scan"),
    "virtual/tiles.py:_reached_block": (
        [VR + "test_tile_scan_blocks_skip_only_tiles_that_reach_none_of_them"], "_scan_reached"),
    "virtual/tiles.py:_block_misses": (
        [VR + "test_tile_scan_blocks_skip_only_tiles_that_reach_none_of_them"], "_scan_reached"),
    "virtual/tiles.py:_seed_rays": ([VR + "test_tile_scan_matches_twin"], "_scan"),
    "virtual/tiles.py:_load_block": ([VR + "test_tile_scan_matches_twin"], "_scan"),
    "virtual/tiles.py:_candidates": ([VR + "test_part_candidates_and_join_match_twins"],
                                     "PartTiles.candidates"),
    "virtual/tiles.py:_join": ([VR + "test_part_candidates_and_join_match_twins"], "joined"),
    "virtual/view.py:_faces_behind": ([V + "test_faces_behind_match_twin"],
                                      "PartView.faces_behind"),
    "virtual/view.py:part_views": ([V + "test_part_views_match_twin"], "reflector_view"),
    "virtual/tiles.py:_rows_of": ([VR + "test_rows_of_matches_twin"], "rows_of"),
    "virtual/tiles.py:_balls": ([VR + "test_part_balls_match_twin_bit_for_bit"],
                                "_parts_balls"),
    "virtual/tiles.py:_tile_bounds": ([VR + "test_tile_bounds_match_twin"], "PartTiles"),
    "virtual/explosion.py:map_coords": ([VE + "test_map_coords_and_vertex_coords_match_twin"],
                                        None),
    "virtual/explosion.py:_vertex_coords": (
        [VE + "test_map_coords_and_vertex_coords_match_twin"], "build_explosion_maps"),
    "virtual/mapfill.py:_span": (FILL, "_fill_triangle"),
    "virtual/mapfill.py:_nearest_filled": ([VE + "test_nearest_filled_matches_twin"],
                                             "_build_layers"),
    "virtual/explosion.py:_focus_sums": ([VE + "test_ray_focus_matches_twin_bit_for_bit"],
                                         None),
    "virtual/explosion.py:_setup_arrays": (
        [VE + "test_map_setup_arrays_match_twin_bit_for_bit"], None),
    "virtual/screen.py:_screen_rows": ([VE + "test_screen_from_world_matches_twin_bit_for_bit"],
                                       None),
    "virtual/screen.py:_screen_from_ndc": (
        [VE + "test_screen_from_world_matches_twin_bit_for_bit"], "_screen_rows"),
    "virtual/part.py:_extent": ([VE + "test_part_extent_matches_twin_bit_for_bit"], None),
    "virtual/explosion.py:_unmark": (
        [VE + "test_lookup_texels_are_the_marked_texels_and_their_boxes",
         VE + "test_maps_built_together_give_each_part_s_maps_at_its_lookups"],
        "build_maps_together"),
    "virtual/explosion.py:_surely_well_posed": (
        [VE + "test_surely_well_posed_never_contradicts_numpy",
         VE + "test_ray_foci_are_each_mesh_s_ray_focus"], "foci_from_sums"),
    "virtual/part.py:_lookup_axis": ([VS + "test_lookup_axis_matches_twin",
                                      VS + "test_parts_extents_are_each_part_s"],
                                     "ExplosionPart"),
    "virtual/explosion.py:_map_frames": ([VS + "test_map_frames_are_map_frame",
                                          VS + "test_parts_map_setups_are_each_part_s"],
                                         "parts_map_setups"),
    "virtual/partsetup.py:_focus_sums_parts": ([VS + "test_parts_foci_are_ray_foci"] + PARTS,
                                               "parts_foci"),
    "virtual/partsetup.py:_extent_parts": ([VS + "test_parts_extents_are_each_part_s"] + PARTS,
                                           "parts_extents"),
    "virtual/partsetup.py:_setup_arrays_parts": (
        [VS + "test_parts_map_setups_are_each_part_s"] + PARTS, "parts_map_setups"),
    "virtual/part.py:_farthest": ([VE + "test_part_extent_matches_twin_bit_for_bit"],
                                  "_extent"),
    "fused.py:fma": ([VE + "test_screen_from_world_matches_twin_bit_for_bit",
                      "tests/test_fused.py::test_fma_rounds_once"], "_screen_rows"),
    "virtual/explosion.py:_build_layers": ([VE + "test_explosion_layers_match_twin"] + PARTS,
                                           "build_explosion_maps"),
    "virtual/explosion.py:_build_layer": ([VE + "test_explosion_layers_match_twin"],
                                          "_build_layers"),
    "virtual/mapfill.py:_clear_unmarked": (
        [VE + "test_maps_built_for_their_lookups_match_whole_maps_there",
         VE + "test_maps_for_lookups_of_a_patch_seen_from_behind"] + PARTS, "_build_layer"),
    "virtual/mapfill.py:_marked_box": (
        [VE + "test_maps_built_for_their_lookups_match_whole_maps_there"], "_build_layer"),
    "virtual/explosion.py:_lookup_at": (
        [VE + "test_maps_built_for_their_lookups_match_whole_maps_there"] + LOOKUP, "_virtual"),
    "virtual/explosion.py:_mark_lookups": (
        [VE + "test_maps_built_for_their_lookups_match_whole_maps_there"],
        "build_explosion_maps"),
    "virtual/explosion.py:_lookup_texels": (
        [VE + "test_lookup_texels_are_the_marked_texels_and_their_boxes"] + PARTS,
        "build_maps_together"),
    "virtual/explosion.py:_texels_box": (
        [VE + "test_lookup_texels_are_the_marked_texels_and_their_boxes"] + PARTS,
        "_build_layer"),
    "virtual/mapfill.py:_holes": (
        [VE + "test_holes_are_the_marked_empty_texels_of_the_box",
         VE + "test_maps_built_for_their_lookups_match_whole_maps_there"], "_build_layer"),
    "virtual/mapfill.py:_fill_holes": (HOLES, "_build_layer"),
    "virtual/mapfill.py:_nearest_held": (HOLES, "_fill_holes"),
    "virtual/mapfill.py:_center_held": (FILL + IDS_AT + HOLES, "_fill_triangle"),
    "virtual/mapfill.py:_edges": (FILL + IDS_AT + HOLES, "_fill_triangle"),
    "virtual/mapfill.py:_row_span": (FILL + IDS_AT + HOLES, "_fill_triangle"),
    "virtual/mapfill.py:_before": (HOLES, "_fill_holes"),
    "virtual/mapfill.py:_holds_at": (HOLES, "_fill_holes"),
    "virtual/mapfill.py:_layer_triangles": (HOLES, "_build_layer"),
    "virtual/mapfill.py:_ids_at_marked": (IDS_AT, "_build_layer"),
    "virtual/mapfill.py:_marked_texels": (
        IDS_AT + [VE + "test_lookup_texels_are_the_marked_texels_and_their_boxes"],
        "_build_layer"),
    "virtual/mapfill.py:_holds": (IDS_AT, "_ids_at_marked"),
    "virtual/mapfill.py:_texel_range": (IDS_AT, "_ids_at_marked"),
    "virtual/mapfill.py:_quad": (IDS_AT, "_ids_at_marked"),
    "virtual/mapfill.py:_fill_triangle": (FILL, None),
    "virtual/mapfill.py:_fill_faces": (FILL, None),
    "virtual/mapfill.py:_extend": (FILL, "_fill_extensions"),
    "virtual/mapfill.py:_fill_extensions": (FILL, None),
    "virtual/explosion.py:_plane_from_map": (
        [VE + "test_plane_and_screen_lookups_match_twin"] + LOOKUP, None),
    "virtual/explosion.py:_plane_of": (
        [VE + "test_plane_and_screen_lookups_match_twin"] + LOOKUP + PARTS, "_plane_from_map"),
    "virtual/explosion.py:_screen_plane": (
        [VE + "test_plane_and_screen_lookups_match_twin"] + LOOKUP, None),
    "virtual/explosion.py:_blend3": (
        [VE + "test_plane_and_screen_lookups_match_twin"] + LOOKUP, "_plane_from_map"),
    "virtual/explosion.py:_unit_or_zero": (
        [VE + "test_plane_and_screen_lookups_match_twin"] + LOOKUP, "_plane_from_map"),
    "virtual/explosion.py:_mirror": (LOOKUP, "_virtual"),
    "virtual/explosion.py:_virtual": (LOOKUP, "virtual_vertices"),
    "virtual/explosion.py:_through_hidden": (LOOKUP + PARTS, "_virtual"),
    "virtual/explosion.py:_through_maps": (LOOKUP + PARTS, "_virtual"),
    "virtual/explosion.py:_mark_parts": (PARTS, "build_maps_together"),
    "virtual/explosion.py:_virtual_parts": (PARTS, "virtual_vertices_together"),
    "virtual/explosion.py:_virtual_chunk": (PARTS, "_virtual_parts"),
    "virtual/tiles.py:_scan_block": ([VR + "test_tile_scan_matches_twin"] + PARTS, "_scan"),
    "virtual/tiles.py:_candidate": ([VR + "test_part_candidates_and_join_match_twins"] + PARTS,
                                    "_candidates"),
    "virtual/tiles.py:_candidates_parts": (PARTS, "scan_parts"),
    "virtual/tiles.py:_join_parts": (PARTS, "scan_parts"),
    "virtual/tiles.py:_part_of_block": (PARTS, "_scan_parts"),
    "virtual/tiles.py:_tile_rays": (PARTS, "_scan_parts"),
    "virtual/tiles.py:_scan_reached_parts": (PARTS, "scan_parts"),
    "virtual/tiles.py:_scan_parts": (PARTS, "scan_parts"),
    "virtual/view.py:face_behind": ([V + "test_faces_behind_match_twin"] + PARTS,
                                    "_faces_behind"),
    "virtual/parts.py:_gather_parts": (PARTS, "parts_vertices"),
    "virtual/parts.py:_scatter_parts": (PARTS, "parts_vertices"),
    "virtual/partpasses.py:part_labels": ([V + "test_part_labels_match_twin"] + PART_PASSES,
                                          None),
    "maps/distance_search.py:search_ray": (SEARCH, "_search_pixels"),
    "maps/distance_search.py:_search_pixels": (SEARCH, None),
    "maps/distance_search.py:sample_layer": (SEARCH, "search_ray"),
    "maps/distance_search.py:_texels": (SEARCH, "search_ray"),
    "maps/distance_search.py:_search_work": (SEARCH, "_search_pixels"),
    "maps/distance_search.py:_search_row": (SEARCH, "_search_pixels"),
    "reflection.py:reflected_ray": ([D + "test_reflected_ray_matches_twin"], None),
    "maps/distance_search.py:_g_of": (SEARCH, "search_ray"),
    "maps/distance_search.py:_g_surface": (SEARCH, "search_ray"),
    "maps/distance_search.py:_distance": (SEARCH, "search_ray"),
    "maps/distance_search.py:_point": (SEARCH, "search_ray"),
    "maps/distance_search.py:_angle": (SEARCH, "search_ray"),
    "screenspace/rays.py:to_screen": ([S + "test_mirror_rays_match_twin"], None),
    "screenspace/rays.py:_rays": ([S + "test_mirror_rays_match_twin"], "mirror_rays"),
    "screenspace/rays.py:_rays_row": ([S + "test_mirror_rays_match_twin"], "mirror_rays"),
    "screenspace/rays.py:distance_at": ([S + "test_distance_at_matches_twin"], None),
    "screenspace/march.py:jitter_offset": ([S + "test_jitter_offset_matches_twin"], None),
    "screenspace/march.py:march_linear": ([S + "test_linear_equals_twin"], None),
    "screenspace/march.py:march_dda": (DDA, None),
    "screenspace/march.py:_store_march": (DDA + [S + "test_hiz_equals_pixel_walk_on_frames"],
                                         "march_all"),
    "screenspace/march.py:_march_all": (DDA + [S + "test_linear_equals_twin"], "march_all"),
    "screenspace/hiz.py:_build": ([S + "test_pyramid_matches_twin"], "build_pyramid"),
    "screenspace/hiz.py:_exit_u": (HIZ, "march_hiz"),
    "screenspace/hiz.py:pixel_overlap": (HIZ, "march_hiz"),
    "screenspace/hiz.py:march_hiz": (HIZ, None),
    "screenspace/hiz.py:_march_hiz_all": ([S + "test_hiz_equals_pixel_walk_on_frames"],
                                          "march_hiz_all"),
    "screenspace/resolve.py:_surface_hit": (RESOLVE, "resolve_hits"),
    "screenspace/resolve.py:resolve_hits": (RESOLVE, None),
    "screenspace/resolve.py:confidence": (RESOLVE, None),
    "screenspace/project.py:project_sources": ([P + "test_projection_and_scatter_match_twin"],
                                               None),
    "screenspace/project.py:scatter_min": ([P + "test_projection_and_scatter_match_twin"], None),
    "screenspace/project.py:_key_at": ([P + "test_fill_matches_twin"], "fill_holes"),
    "screenspace/project.py:fill_holes": ([P + "test_fill_matches_twin"], None),
    "screenspace/project.py:decode": ([P + "test_decode_matches_twin"], None),
}


def _is_njit(decorator: ast.expr) -> bool:
    node = decorator.func if isinstance(decorator, ast.Call) else decorator
    name = node.attr if isinstance(node, ast.Attribute) else getattr(node, "id", "")
    return name in ("njit", "jit")


def _compiled_names(node: ast.AST) -> list[str]:
    """The names a statement compiles: a function decorated with @njit / @jit, or an
    assignment `name = njit(...)(function)` (a compiled copy of a plain function)."""
    if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
        return [node.name] if any(_is_njit(d) for d in node.decorator_list) else []
    if (isinstance(node, ast.Assign) and isinstance(node.value, ast.Call)
            and isinstance(node.value.func, ast.Call) and _is_njit(node.value.func)):
        return [t.id for t in node.targets if isinstance(t, ast.Name)]
    return []


def njit_kernels() -> set[str]:
    """Every @njit / @jit function in reflectcli (and every `njit(...)(f)` copy), as
    'path under reflectcli:name'."""
    found = set()
    package = ROOT / "reflectcli"
    for path in sorted(package.rglob("*.py")):
        tree = ast.parse(path.read_text(), str(path))
        for node in ast.walk(tree):
            for name in _compiled_names(node):
                found.add(f"{path.relative_to(package).as_posix()}:{name}")
    return found


def test_every_kernel_has_a_twin_test():
    kernels = njit_kernels()
    assert len(kernels) > 40  # the scan finds the kernels at all
    missing = sorted(kernels - KERNELS.keys())
    stale = sorted(KERNELS.keys() - kernels)
    assert not missing, f"@njit kernels with no twin test in KERNELS: {missing}"
    assert not stale, f"KERNELS entries for kernels that no longer exist: {stale}"


def _test_functions(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(), str(path))
    return {n.name for n in tree.body if isinstance(n, ast.FunctionDef)
            and n.name.startswith("test_")}


def test_every_named_twin_test_exists():
    cache: dict[str, set[str]] = {}
    for kernel, (tests, _) in KERNELS.items():
        assert tests, kernel
        for ref in tests:
            file, name = ref.split("::")
            if file not in cache:
                cache[file] = _test_functions(ROOT / file)
            assert name in cache[file], f"{kernel}: no test {ref}"


def test_naive_twins_name_their_kernels():
    """Each twin in tests/naive.py (and tests/naive_screenspace.py) says in its docstring
    which kernel it twins, and every kernel name in KERNELS (bar helpers reached through a
    caller) is named by some twin."""
    import naive
    import naive_screenspace  # the screen-space kernels' twins (issue 15)

    docs = " ".join((getattr(mod, n).__doc__ or "") for mod in (naive, naive_screenspace)
                    for n in dir(mod)
                    if callable(getattr(mod, n)) and not n.startswith("_")
                    and getattr(getattr(mod, n), "__module__", "") == mod.__name__)
    for kernel, (_, via) in KERNELS.items():
        path, name = kernel.split(":")
        if via is None or not name.startswith("_"):
            dotted = path.removesuffix(".py").replace("/", ".")
            # the name bare, or under a run of the module's own dotted path (refine.x,
            # maps.warp.x): screenspace.rays.mirror_rays does not name
            # virtual.refine.mirror_rays
            own = f".reflectcli.{dotted}."
            named = any(f".{m.group(1)}" in own for m in
                        re.finditer(rf"(?<![\w.])((?:\w+\.)*){re.escape(name)}\b", docs))
            assert named, f"no twin names {kernel}"
