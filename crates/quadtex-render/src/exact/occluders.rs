//! Occluders no centre sees: the mesh triangles in front of what a
//! support's cut shows ([`Occluders::search`]), and whether anything lies
//! in front of the one primitive a pixel's centres see
//! ([`in_front_within`]). A far ridge seen as a band thinner than a pixel,
//! between two rows of centres, hides part of the slope behind it, yet no
//! centre sees it and the slope's triangles tile the support
//! (docs/algorithm.md §8, "Occluders no centre sees").

use quadtex_core::ConvexPolygon;

use crate::caster::{Seen, surface_and_triangle};
use crate::scene::Scene;
use crate::view::View;

use super::cutting::{Bounds, Cut, Regions, boxes_apart, overlap};
use super::views::{SurfaceViews, ViewMemo, ViewRef, candidate_view};

/// The search for occluders no centre sees: mesh triangles in front of a
/// visible region of a support's cut (within `cap` of them).
pub(super) struct Occluders<'s, 'a> {
    pub(super) scene: &'s Scene,
    pub(super) cache: &'a SurfaceViews,
    pub(super) support: &'s ConvexPolygon,
    pub(super) cap: usize,
}

/// Whether a primitive other than `id` lies in front of `view` (a
/// plane's, quad's or triangle's, or a sphere's holding `area`) somewhere
/// in screen polygon `area`: a plane, quad or mesh triangle nearer by more
/// than `10⁻⁹` of the depth at a vertex of its part of `area`, the
/// triangles from those [`SurfaceViews::meshes_nearer`] lists under
/// `view`'s farthest point in `area`; or another sphere whose outline's
/// box meets `area`'s. A triangle with no view counts as in front.
///
/// The vertices decide. Against a plane, the difference of two planar
/// primitives' inverse depths is affine on the screen. Against a sphere
/// (the camera outside it), the inverse depth of its near side along the
/// camera's ray through `s` is `(m·d + √Q(d))/k` with `d` the ray's
/// direction (affine in `s`), `m` the centre from the camera, `k = |m|² −
/// r²` and `Q(d) = (m·d)² − k|d|²` a form of one positive and two
/// negative squares: inside the outline (`Q > 0`) `√Q` is concave (the
/// reverse triangle inequality of such forms), so the primitive's inverse
/// depth less the sphere's is convex and greatest at a vertex. The
/// sphere's depth, the inverse of a concave function there, is convex too:
/// its farthest point in `area` is at a vertex.
pub(super) fn in_front_within<'a>(
    (scene, cache): (&Scene, &'a SurfaceViews),
    id: Seen,
    view: &ViewRef<'_>,
    area: &ConvexPolygon,
    memo: &mut ViewMemo,
    planes: &mut Vec<[f64; 4]>,
    buffers: &mut OccluderBuffers<'a>,
) -> bool {
    let own = surface_and_triangle(id).0;
    // Another sphere whose outline's box meets the area, counted as in front.
    if !cache.spheres_miss_except(area.bounds(), own) {
        return true;
    }
    let candidate = &mut buffers.candidate;
    let nearer = |seen: &View, candidate: &ConvexPolygon| {
        (candidate.vertices().iter()).any(|&v| seen.depth_at(v) < view.depth_at(v) * (1.0 - 1e-9))
    };
    for (surface, seen) in cache.planar_views().iter().enumerate() {
        if let Some(seen) = seen
            && surface != own
        {
            seen.region_into(area, candidate);
            if nearer(seen, candidate) {
                return true;
            }
        }
    }
    let far = farthest_depth(view, area);
    cache.meshes_nearer(
        scene,
        area,
        far,
        planes,
        &mut buffers.nearer,
        |other, near, _| {
            if other == id || near >= far {
                return false;
            }
            let Some(seen) = candidate_view(scene, cache, memo, other) else {
                return true;
            };
            let Some(seen) = seen.as_ref().and_then(ViewRef::planar) else {
                return seen.is_some();
            };
            seen.region_into(area, candidate);
            nearer(seen, candidate)
        },
    )
}

/// The buffers of [`Occluders::search`].
#[derive(Default)]
pub(super) struct OccluderBuffers<'a> {
    /// The ids tried, sorted.
    tried: Vec<Seen>,
    /// Each visible region's view, box and farthest depth.
    shown: Vec<(usize, Bounds, f64)>,
    /// The triangles [`SurfaceViews::meshes_nearer`] lists.
    nearer: Vec<(u32, u32, f32, [f32; 4])>,
    /// A candidate's region.
    candidate: ConvexPolygon,
    /// The occluders found, to join the list.
    joined: Vec<(Seen, ViewRef<'a>, ConvexPolygon)>,
}

impl<'a> Occluders<'_, 'a> {
    /// Adds to the list (`views`, `tried`, `regions`) every mesh triangle
    /// not tried whose region of the support overlaps a visible region of
    /// `cut` and lies in front of its view there (decided at the overlap's
    /// centroid, as [`Order::front_to_back`] decides; an overlap of at
    /// most the sliver area decides nothing, its area in the bound where
    /// no larger one shows the candidate in front): the candidates are
    /// the triangles nearer somewhere than the farthest point the cut
    /// shows ([`SurfaceViews::meshes_nearer`]), and a candidate is tested
    /// against a visible region only where its least depth is nearer than
    /// that region's farthest point and its box meets that region's. Past the cap, an occluder's region's
    /// area joins the cut's unaccounted weight (the bound's). Returns how
    /// many joined; `None` when a candidate has no view.
    pub(super) fn search(
        &self,
        views: &mut Vec<ViewRef<'a>>,
        tried: &mut Vec<(Seen, Option<usize>)>,
        regions: &mut Regions,
        cut: &mut Cut,
        memo: &mut ViewMemo,
        (planes, buffers): (&mut Vec<[f64; 4]>, &mut OccluderBuffers<'a>),
    ) -> Option<usize> {
        let (scene, cache, support) = (self.scene, self.cache, self.support);
        let OccluderBuffers {
            tried: ids,
            shown,
            nearer,
            candidate,
            joined,
        } = buffers;
        shown.clear();
        let mut farthest = f64::NEG_INFINITY;
        for (i, r) in cut.visible(regions) {
            let far = farthest_depth(&views[i], r);
            farthest = farthest.max(far);
            shown.push((i, r.bounds(), far));
        }
        if farthest == f64::NEG_INFINITY {
            return Some(0);
        }
        ids.clear();
        ids.extend(tried.iter().map(|&(id, _)| id));
        ids.sort_unstable();
        let (mut added, mut missing) = (0, false);
        joined.clear();
        let mut left_out = 0.0;
        let sliver_area = cut.sliver_area;
        cache.meshes_nearer(
            scene,
            support,
            farthest,
            planes,
            nearer,
            |id, near, reach| {
                // Nearer than some visible region's farthest point where its
                // box meets that region's, or it hides nothing.
                if shown
                    .iter()
                    .all(|&(_, shown_box, far)| near >= far || boxes_apart(reach, shown_box))
                    || ids.binary_search(&id).is_ok()
                {
                    return false;
                }
                let view = match candidate_view(scene, cache, memo, id) {
                    Some(Some(view)) => view,
                    Some(None) => return false,
                    None => {
                        missing = true;
                        return true;
                    }
                };
                view.region_into(support, candidate);
                if candidate.is_empty() {
                    return false;
                }
                let bounds = candidate.bounds();
                // An overlap of a hair (rounding along an edge two triangles
                // share) decides nothing, as in the order: where the
                // candidate is in front over hairs alone, their area goes to
                // the bound.
                let (mut in_front, mut hairs) = (false, 0.0);
                for (&(i, shown_box, far), (_, r)) in shown.iter().zip(cut.visible(regions)) {
                    if near >= far || boxes_apart(bounds, shown_box) {
                        continue;
                    }
                    let Some(o) = overlap(candidate, r) else {
                        continue;
                    };
                    let c = o.centroid();
                    if view.depth_at(c) < views[i].depth_at(c) {
                        let area = o.area();
                        if area > sliver_area {
                            in_front = true;
                            break;
                        }
                        hairs += area;
                    }
                }
                if !in_front {
                    left_out += hairs;
                } else if added < self.cap {
                    added += 1;
                    joined.push((id, view, candidate.clone()));
                } else {
                    left_out += candidate.area();
                }
                false
            },
        );
        if missing {
            return None;
        }
        cut.unaccounted += left_out;
        for (id, view, region) in joined.drain(..) {
            tried.push((id, Some(views.len())));
            views.push(view);
            regions.next_slot().clone_from(&region);
            regions.keep_slot();
        }
        Some(added)
    }
}

/// The farthest depth `view` shows over convex polygon `polygon`: at a
/// vertex, for a planar primitive (its inverse depth is affine on the
/// screen) and for a sphere holding the polygon (its depth is convex
/// there, [`in_front_within`]).
fn farthest_depth(view: &ViewRef<'_>, polygon: &ConvexPolygon) -> f64 {
    (polygon.vertices().iter()).fold(f64::NEG_INFINITY, |d, &v| d.max(view.depth_at(v)))
}
