//! The exact pixel itself ([`exact_pixel`]) and the buffers a thread
//! reuses from pixel to pixel ([`Scratch`]).

use std::borrow::Cow;
use std::rc::Rc;

use quadtex_core::{ConvexPolygon, FilterOptions, PixelFilter, Rgba};

use crate::caster::{Seen, seen_id, surface_and_triangle};
use crate::frame::{Frame, sky};
use crate::pixel::Neighbourhood;
use crate::scene::{Geometry, Scene};
use crate::span::{SpanQuery, UniformSpan};
use crate::stats::PixelStats;
use crate::view::View;

use super::cutting::Flood;
use super::cutting::{Cut, Order, Regions, overlap, push_region};
use super::lighting::{Shading, shade_region, shade_span_pixel, tint_and_light};
use super::occluders::{OccluderBuffers, Occluders, in_front_within};
use super::screen_cells::ScreenCells;
use super::sky::{
    SkySpan, Whole, sky_at_centre, sky_clear_above, sky_integral, sky_range, sky_step,
    sky_tolerance, views_miss,
};
use super::sphere::SphereView;
use super::views::{Confirmed, SurfaceViews, ViewMemo, ViewRef, candidate_view};
use super::{GAP_AREA, MAX_GAP_PRIMITIVES, MAX_MESH_SCAN};

/// The filtered colour of pixel `(x, y)` whose neighbourhood's centres see
/// `near.primitives` (and the sky if `near.sky`), or `None` when a
/// candidate has no view (a sphere reaching behind the camera's plane):
/// the caller then takes the tangent-plane path. `scratch`: the calling thread's buffers.
pub(crate) fn exact_pixel<'a>(
    frame: &Frame<'_>,
    options: &FilterOptions,
    filter: PixelFilter,
    (x, y): (u32, u32),
    near: &Neighbourhood<'_, 'a>,
    scratch: &mut Scratch<'a>,
    stats: &mut PixelStats,
) -> Option<Rgba> {
    let scene = frame.scene;
    let centre = [f64::from(x) + 0.5, f64::from(y) + 0.5];
    let support = filter.support(centre);
    let pixel = ExactPixel {
        shading: Shading {
            frame,
            filter,
            centre,
            options,
            support: support.bounds(),
            share: 1.0,
        },
        at: (x, y),
        support,
        cache: near.views,
        cap: MAX_GAP_PRIMITIVES,
    };
    let (cache, support, candidates) = (near.views, &pixel.support, near.primitives);
    // One primitive over the whole support: one integral.
    if let [id] = candidates
        && !near.sky
        && let Some(view) = candidate_view(scene, cache, &mut scratch.memo, *id)?
    {
        let colour = match &view {
            // Held inside its outline's chords, with nothing in front of it
            // there that no centre sees (a wire thinner than a pixel
            // between two rows of centres).
            ViewRef::Sphere(sphere) => (sphere.holds(&pixel.support)
                && !in_front_within(
                    (scene, cache),
                    *id,
                    &view,
                    &pixel.support,
                    &mut scratch.memo,
                    &mut scratch.planes,
                    &mut scratch.occluders,
                ))
            .then(|| pixel.one_sphere(sphere, stats)),
            // Unless a mesh triangle no centre sees lies in front of it (the
            // general path's occluders' search then takes the pixel).
            _ => view.planar().and_then(|view| {
                // A span shares one answer among its pixels: only where the
                // whole run is clear of such triangles.
                let run = scratch.nothing_in_front(&pixel, *id, view, near.run)?;
                pixel.one_primitive(
                    *id,
                    view,
                    run,
                    (&mut scratch.uniform_span, &mut scratch.screen_cells),
                    stats,
                )
            }),
        };
        if colour.is_some() {
            return colour;
        }
    }
    // Only the sky in reach: the sky over the whole support unless a plane,
    // quad or mesh triangle no centre sees reaches into it (the case the
    // general path below covers).
    if candidates.is_empty()
        && near.sky
        && views_miss(cache, &mut scratch.sky_span, filter, (x, y), support)
        && cache.spheres_miss(support.bounds())
        && !cache.meshes_in(scene, support, &mut scratch.planes, |_| true)
    {
        let (c, w) = sky_integral(
            scene,
            support,
            Whole::Yes,
            filter,
            centre,
            sky_tolerance(options),
        );
        return Some(mean(c, w));
    }
    pixel.list_candidates(candidates, scratch)?;
    let mut parts = PixelStats::default();
    let sums = if pixel.outline_needs_cells(scratch) {
        pixel.cell_by_cell(candidates, scratch, &mut parts)?
    } else {
        pixel.cut_and_shade(scratch, &mut parts)?
    };
    Some(pixel.finish(sums, parts, stats))
}

/// Share of the error bound a sphere's outline may leave out of a
/// support, as its chords do ([`SphereView::sliver_bound`]), before the
/// support is taken quarter by quarter, each clipped by its own chords:
/// where a small sphere's outline crosses a tent's or Mitchell's support,
/// the ten chords one polygon holds leave out more than the bound.
const OUTLINE_SHARE: f64 = 0.5;

/// The smallest cell side (pixels) a support is split to for a sphere's
/// outline ([`OUTLINE_SHARE`]).
const SMALLEST_CELL: f64 = 0.5;

/// One exact pixel's question, what its steps share: the shading of its
/// regions (frame, filters, centre), where it is, its filter's support,
/// and the frame's views.
pub(super) struct ExactPixel<'p, 'a> {
    pub(super) shading: Shading<'p>,
    pub(super) at: (u32, u32),
    pub(super) support: ConvexPolygon,
    pub(super) cache: &'a SurfaceViews,
    /// Most primitives the flood, the gaps' search and each pass of the
    /// occluders' search add to the list: [`MAX_GAP_PRIMITIVES`] a pixel.
    pub(super) cap: usize,
}

/// The sums a pixel's colour is the mean of: `Σ colour·k`, `Σ k`, and the
/// error bounds' sum, added region by region in a fixed order.
#[derive(Default, Clone)]
pub(super) struct Sums {
    colour: [f64; 4],
    weight: f64,
    bound: f64,
}

impl Sums {
    fn add(&mut self, c: [f64; 4], w: f64, b: f64) {
        for (a, v) in self.colour.iter_mut().zip(c) {
            *a += v;
        }
        self.weight += w;
        self.bound += b;
    }
}

impl<'a> ExactPixel<'_, 'a> {
    /// The pixel when the one primitive its centres see, `view` (`id`),
    /// covers its whole support: its run's span's answer where one
    /// stands, else one integral. `None` when its region is not the whole
    /// support (the general path then takes the pixel).
    fn one_primitive(
        &self,
        id: Seen,
        view: &View,
        run: u32,
        (uniform_span, screen_cells): (&mut UniformSpan, &mut ScreenCells),
        stats: &mut PixelStats,
    ) -> Option<Rgba> {
        let Shading {
            frame,
            filter,
            options,
            ..
        } = self.shading;
        let (support, (x, y)) = (&self.support, self.at);
        let mut sums = Sums::default();
        let mut parts = PixelStats::default();
        // A run of such pixels: one answer for a span of them.
        let query = SpanQuery {
            frame,
            view,
            filter,
            options,
        };
        let answer = uniform_span.answer(&query, (x, y), id, run);
        // Counted on this pixel alone, not on the span's copies of it.
        stats.filter.traversal.queries += uniform_span.take_lookups();
        if let Some(answer) = answer {
            let (c, w) = shade_span_pixel(&self.shading, view, support, &answer, &mut parts);
            sums.add(c, w, 0.0);
            parts.weight_error = weight_error(w);
            parts.filter.record_bound(0.0);
            stats.merge_parts(&parts);
            let colour = mean(sums.colour, sums.weight);
            // The weight is the same bits at every pixel: the box's is the
            // support's area, 1 (its corners are multiples of ½, exact in
            // floats, and so are their products at pixel coordinates below
            // 2³²); the tent's and Mitchell's integrate the support moved
            // to the centre, `centre ± r − centre`, exactly `±r`. With the
            // light known, every pixel of the span comes out as this one.
            if answer.light.is_some() && (filter != PixelFilter::Box || w == 1.0) {
                uniform_span.set_fill(colour, parts);
            }
            return Some(colour);
        }
        let region = view.region(support);
        let whole =
            matches!(region, Cow::Borrowed(_)) || region.area() >= support.area() * (1.0 - 1e-12);
        if !whole {
            return None;
        }
        // The sun over the pixel's run, when one test settled it for
        // all of the run (the span that failed was refused for its
        // texture), else the pixel's own shadow ray.
        let light = uniform_span.run_light((x, y), id);
        // The tent's and Mitchell's supports over a shallow repeated
        // texture: from the thread's screen cells, each integrated once
        // for the pixels sharing it.
        let by_cells = frame
            .texture(view.surface())
            .filter(|texture| texture.scans_screen_cells(filter))
            .and_then(|texture| {
                screen_cells.pixel(
                    texture,
                    view,
                    id,
                    filter,
                    (x, y),
                    options,
                    &mut parts.filter,
                )
            });
        let (c, w, b) = match by_cells {
            Some((texture_colour, w)) => {
                parts.textured = 1;
                let c = tint_and_light(frame, view, &region, Some(texture_colour), w, light);
                (c, w, 0.0)
            }
            None => shade_region(&self.shading, view, &region, light, &mut parts),
        };
        sums.add(c, w, b);
        parts.weight_error = weight_error(w);
        stats.merge_parts(&parts);
        stats
            .filter
            .record_bound_against(b / w.abs().max(1e-300), self.shading.options.target_bound());
        Some(mean(sums.colour, sums.weight))
    }

    /// The pixel when the one sphere its centres see holds its whole
    /// support inside its outline's chords ([`SphereView::holds`]) and
    /// nothing lies in front of it there ([`in_front_within`]), as the
    /// caller has found: one call to the sphere's shading.
    fn one_sphere(&self, sphere: &SphereView, stats: &mut PixelStats) -> Rgba {
        let mut parts = PixelStats::default();
        let (c, w, b) = sphere.shade(&self.shading, &self.support, &mut parts);
        parts.weight_error = weight_error(w);
        stats.merge_parts(&parts);
        stats
            .filter
            .record_bound_against(b / w.abs().max(1e-300), self.shading.options.target_bound());
        mean(c, w)
    }

    /// Lists the views of the primitives the centres see (`candidates`)
    /// and of every other plane, quad and triangle of a small mesh a
    /// centre sees, which may reach into the support unseen, with their
    /// regions of the support. `None` when a candidate has no view.
    pub(super) fn list_candidates(
        &self,
        candidates: &[Seen],
        scratch: &mut Scratch<'a>,
    ) -> Option<()> {
        let (scene, cache) = (self.shading.frame.scene, self.cache);
        let Scratch {
            views,
            tried,
            regions,
            memo,
            ..
        } = scratch;
        views.clear();
        // Every primitive tried so far and its view's index (none: edge-on).
        tried.clear();
        for &id in candidates {
            let view = candidate_view(scene, cache, memo, id)?;
            tried.push((id, view.is_some().then_some(views.len())));
            views.extend(view);
        }
        // The centres in reach may all miss a primitive that still reaches into
        // the support (a quad's corner, a triangle's tip near a vertex): every
        // plane and quad of the scene is a candidate here, and every triangle
        // of a (small) mesh one of the centres sees.
        let (lo, hi) = self.support.bounds();
        for (surface, s) in scene.surfaces.iter().enumerate() {
            let seen_here = |t: u32| candidates.contains(&seen_id(surface, t));
            match &s.geometry {
                Geometry::Plane { .. } | Geometry::Quad { .. } if !seen_here(0) => {
                    let view = cache.get(scene, surface, 0);
                    tried.push((seen_id(surface, 0), view.is_some().then_some(views.len())));
                    views.extend(view);
                }
                Geometry::Mesh(mesh)
                    if mesh.len() <= MAX_MESH_SCAN
                        && candidates
                            .iter()
                            .any(|&id| surface_and_triangle(id).0 == surface) =>
                {
                    for t in 0..mesh.len() as u32 {
                        if seen_here(t) {
                            continue;
                        }
                        let view = s
                            .geometry
                            .planar(t)
                            .and_then(|p| View::new(scene, surface, &p));
                        tried.push((seen_id(surface, t), view.is_some().then_some(views.len())));
                        views.extend(view.map(|v| ViewRef::Built(Rc::new(v))));
                    }
                }
                Geometry::Sphere { .. } if !seen_here(0) => {
                    if let Some(sphere) = cache.spheres.get(surface).and_then(Option::as_ref)
                        && !sphere.misses_box(lo, hi)
                    {
                        tried.push((seen_id(surface, 0), Some(views.len())));
                        views.push(ViewRef::Sphere(sphere));
                    }
                }
                _ => {}
            }
        }
        regions.clear();
        for v in views.iter() {
            push_region(regions, v, &self.support);
        }
        Some(())
    }

    /// Where the listed regions leave part of the support uncovered, lists
    /// the mesh triangles across the edges of those listed
    /// ([`Flood::spread`]), each confirmed by a camera ray; an occluder a
    /// ray meets instead undoes the spread and joins the list. Returns how
    /// many primitives joined from the gaps (the occluder, if any); `None`
    /// when the occluder has no view.
    fn spread_to_neighbours(&self, scratch: &mut Scratch<'a>) -> Option<usize> {
        let Shading { frame, .. } = self.shading;
        let (scene, cache, support) = (frame.scene, self.cache, &self.support);
        let Scratch {
            views,
            tried,
            regions,
            memo,
            flooded,
            confirmed,
            ..
        } = scratch;
        let mut found = 0;
        let covered: f64 = regions.iter().map(ConvexPolygon::area).sum();
        if covered < support.area() * (1.0 - GAP_AREA) {
            let flood = Flood {
                scene,
                cache,
                support,
                cap: self.cap,
            };
            let (listed, tried_before) = (views.len(), tried.len());
            flood.spread(views, regions, tried, memo, flooded);
            // Each new triangle is confirmed, as a gap's would be, by the ray
            // through its region's centroid (or one a pixel or two back in the
            // row). A nearer primitive there is an occluder no centre sees (a
            // far hill's crest), in front of triangles the flood listed that it
            // may hide beyond the ray: the flood is undone, the occluder joins
            // the list, and the gaps are searched as without a flood.
            let mut occluder = None;
            for &v in flooded.iter() {
                let id = seen_id(views[v].surface(), views[v].triangle().unwrap_or(0));
                // Keyed by the column the region lies in (a shared cut's
                // regions span several; a centroid left of the image, in
                // a tent's or Mitchell's support, saturates to column 0).
                let c = regions[v].centroid();
                let x = c[0].floor() as u32;
                if confirmed.recent(id, x) {
                    continue;
                }
                let hit = cache.camera_hit(frame, c, Some(id));
                match hit.map(|(surface, hit)| seen_id(surface, hit.triangle)) {
                    Some(seen) if seen == id => confirmed.insert(id, x),
                    // One the list holds: their order settles it.
                    Some(seen) if tried.iter().any(|(t, _)| *t == seen) => {}
                    seen => {
                        occluder = Some(seen);
                        break;
                    }
                }
            }
            if let Some(seen) = occluder {
                views.truncate(listed);
                regions.truncate(listed);
                tried.truncate(tried_before);
                if let Some(seen) = seen
                    && !tried.iter().any(|(t, _)| *t == seen)
                {
                    found += 1;
                    let view = candidate_view(scene, cache, memo, seen)?;
                    if let Some(view) = &view {
                        push_region(regions, view, support);
                    }
                    tried.push((seen, view.is_some().then_some(views.len())));
                    views.extend(view);
                }
            }
        }
        Some(found)
    }

    /// Searches what no listed primitive covers, the cut's parts left:
    /// the primitive the ray through each gap's centroid meets, or the
    /// mesh triangles that reach into a gap whose ray meets nothing, join
    /// the list (after `found` joined before, up to the pixel's cap,
    /// [`MAX_GAP_PRIMITIVES`]) and the cut takes them, until no gap adds
    /// one; the gaps left go to `scratch.gaps`. `None` when a primitive
    /// found has no view.
    fn search_gaps(&self, mut found: usize, scratch: &mut Scratch<'a>) -> Option<()> {
        let Shading { frame, .. } = self.shading;
        let (scene, cache, support) = (frame.scene, self.cache, &self.support);
        let Scratch {
            views,
            tried,
            regions,
            gaps,
            cut,
            planes,
            binned,
            memo,
            occluders,
            ..
        } = scratch;
        let mut occluder_passes = 0;
        loop {
            // What no primitive in the list covers is sky, or primitives
            // between the centres (a large mesh's triangles smaller than a
            // pixel): the one the ray through a gap's centroid meets joins the
            // list, and the support is cut again (it may hide parts of the
            // others).
            gaps.clear();
            let mut grew = false;
            let listed = views.len();
            for r in cut.remaining.drain(..) {
                let c = r.centroid();
                let Some((surface, hit)) = cache.camera_hit(frame, c, None) else {
                    // The ray meets nothing, but a mesh's triangles may still
                    // reach into the gap around it: each one whose region
                    // overlaps the gap joins the list.
                    let mut more = false;
                    cache.meshes_in_gap(scene, &r, planes, binned, |id| {
                        if tried.iter().any(|(t, _)| *t == id) {
                            return false;
                        }
                        let Some(Some(view)) = candidate_view(scene, cache, memo, id) else {
                            return false;
                        };
                        let region = regions.next_slot();
                        view.region_into(support, region);
                        if overlap(region, &r).is_none() {
                            return false;
                        }
                        if found == self.cap {
                            more = true;
                            return true;
                        }
                        found += 1;
                        tried.push((id, Some(views.len())));
                        views.push(view);
                        regions.keep_slot();
                        grew = true;
                        false
                    });
                    gaps.push((r, if more { Gap::SkyAmong } else { Gap::Sky }));
                    continue;
                };
                let id = seen_id(surface, hit.triangle);
                if let Some(&(_, view)) = tried.iter().find(|(t, _)| *t == id) {
                    gaps.push((r, Gap::Seen(id, view)));
                    continue;
                }
                let view = if found < self.cap {
                    found += 1;
                    let view = candidate_view(scene, cache, memo, id)?;
                    if let Some(v) = &view {
                        push_region(regions, v, support);
                        grew = true;
                    }
                    tried.push((id, view.is_some().then_some(views.len())));
                    views.extend(view);
                    tried.last().and_then(|t| t.1)
                } else {
                    None
                };
                gaps.push((r, Gap::Seen(id, view)));
            }
            if !grew {
                // The gaps are settled: what remains to find are triangles
                // in front of what the cut shows that no centre saw (a far
                // ridge's crest between two rows of centres). Once more
                // after any joined, for the gaps they may leave.
                if occluder_passes == 2 {
                    return Some(());
                }
                occluder_passes += 1;
                let listed = views.len();
                let found = Occluders {
                    scene,
                    cache,
                    support,
                    cap: self.cap,
                }
                .search(views, tried, regions, cut, memo, (planes, occluders))?;
                if found == 0 {
                    return Some(());
                }
                cut.remaining.extend(gaps.drain(..).map(|(r, _)| r));
                for v in listed..views.len() {
                    cut.insert(v, views, regions);
                }
                continue;
            }
            // New primitives that overlap none listed (a mesh's triangles
            // around those the centres see) only fill gaps: the rest of the
            // cut stands. Otherwise the support is cut again.
            let overlaps = (listed..views.len()).any(|v| {
                (0..views.len()).any(|u| u != v && overlap(&regions[u], &regions[v]).is_some())
            });
            cut.remaining.extend(gaps.drain(..).map(|(r, _)| r));
            if overlaps {
                for v in listed..views.len() {
                    cut.insert(v, views, regions);
                }
            } else {
                for (v, region) in regions.iter().enumerate().skip(listed) {
                    cut.take(v, region);
                }
            }
        }
    }

    /// Whether a sphere listed (`scratch.views`) leaves more of the
    /// support out by its chords than [`OUTLINE_SHARE`] of the support's
    /// share of the bound, where the support is more than a half pixel
    /// wide.
    fn outline_needs_cells(&self, scratch: &Scratch<'a>) -> bool {
        let Some(tolerance) = self.shading.options.target_bound() else {
            return false;
        };
        let (lo, hi) = self.support.bounds();
        if hi[0] - lo[0] <= SMALLEST_CELL {
            return false;
        }
        let Shading {
            filter,
            centre,
            share,
            ..
        } = self.shading;
        scratch.views.iter().any(|v| {
            matches!(v, ViewRef::Sphere(sphere)
                if sphere.sliver_bound(&self.support, filter, centre)
                    > OUTLINE_SHARE * tolerance * share)
        })
    }

    /// The sums of the general path taken over each quarter of the
    /// support in turn, each cut and shaded as a support of its own with
    /// the same filter centre (its share of the bound its weight's
    /// magnitude), and
    /// split again while [`ExactPixel::outline_needs_cells`] says so: the
    /// sums add up to the support's, and a sphere's outline is clipped by
    /// chords over each quarter's angles only.
    fn cell_by_cell(
        &self,
        candidates: &[Seen],
        scratch: &mut Scratch<'a>,
        parts: &mut PixelStats,
    ) -> Option<Sums> {
        let (lo, hi) = self.support.bounds();
        // Halves of ½, 1, 2 or 4: every quarter's corners exact.
        let side = 0.5 * (hi[0] - lo[0]);
        let Shading { filter, centre, .. } = self.shading;
        let mut sums = Sums::default();
        for (i, j) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
            let (x0, y0) = (lo[0] + side * i, lo[1] + side * j);
            let support = ConvexPolygon::rect(x0, y0, x0 + side, y0 + side);
            let cell = ExactPixel {
                // The quarter's weight's magnitude (the filter integrates
                // to 1 over the pixel's support): where Mitchell's lobes
                // change sign within a quarter the shares add up to a
                // little more than 1 (about 1.1 at 1-pixel cells), and
                // give less to the cells the filter barely weighs than
                // their area would (measured: fewer pixels above the
                // target than shares by area).
                shading: Shading {
                    support: support.bounds(),
                    share: filter.integral(&support, centre).abs().min(1.0),
                    ..self.shading
                },
                at: self.at,
                support,
                cache: self.cache,
                cap: self.cap,
            };
            cell.list_candidates(candidates, scratch)?;
            let part = if cell.outline_needs_cells(scratch) {
                cell.cell_by_cell(candidates, scratch, parts)?
            } else {
                cell.cut_and_shade(scratch, parts)?
            };
            sums.add(part.colour, part.weight, part.bound);
        }
        Some(sums)
    }

    /// The general path after the candidates are listed: their
    /// neighbours spread to, the support cut among them, the gaps searched
    /// and the cut shaded.
    fn cut_and_shade(&self, scratch: &mut Scratch<'a>, parts: &mut PixelStats) -> Option<Sums> {
        self.cut(scratch)?;
        let mut sums = [Sums::default()];
        self.shade_cut(
            scratch,
            std::slice::from_ref(self),
            &mut sums,
            std::slice::from_mut(parts),
        )?;
        let [sums] = sums;
        Some(sums)
    }

    /// The support cut among the listed candidates: their neighbours
    /// spread to, the support cut front to back, the gaps searched
    /// (`scratch.cut`, `scratch.gaps`). `None` when a primitive found has
    /// no view.
    pub(super) fn cut(&self, scratch: &mut Scratch<'a>) -> Option<()> {
        let found = self.spread_to_neighbours(scratch)?;
        let Scratch {
            views,
            regions,
            cut,
            order,
            ..
        } = scratch;
        cut.among(views, regions, &self.support, order);
        self.search_gaps(found, scratch)
    }

    /// The pixel's colour from its sums, its statistics recorded.
    pub(super) fn finish(&self, sums: Sums, mut parts: PixelStats, stats: &mut PixelStats) -> Rgba {
        parts.weight_error = weight_error(sums.weight);
        stats.merge_parts(&parts);
        stats.filter.record_bound_against(
            sums.bound / sums.weight.abs().max(1e-300),
            self.shading.options.target_bound(),
        );
        mean(sums.colour, sums.weight)
    }

    /// The sums of the support's cut, added into `sums` of `pixels`: the
    /// pixel itself, or the pixels of a shared cut side by side, each a column
    /// one wide from the support's left side ([`by_column`]): each
    /// visible region shaded, the slivers and the gaps as [`Gap`] says,
    /// each piece by the pixel it lies in, and the weight the cut left
    /// unaccounted in every pixel's bound (where in the support it lies is
    /// not known). `None` when a gap's primitive has no view.
    pub(super) fn shade_cut(
        &self,
        scratch: &mut Scratch<'a>,
        pixels: &[ExactPixel<'_, 'a>],
        sums: &mut [Sums],
        parts: &mut [PixelStats],
    ) -> Option<()> {
        let Shading { frame, .. } = self.shading;
        let (scene, cache) = (frame.scene, self.cache);
        let Scratch {
            views,
            regions,
            gaps,
            cut,
            memo,
            columns,
            ..
        } = scratch;
        let left = self.support.bounds().0[0];
        // Full contrast, or the sky's range where that is larger.
        let contrast = sky_range(scene).max(1.0);
        // Weight no region has, or two have (|k| ≤ 1 for every pixel filter):
        // at most the larger of full contrast and the sky's range off.
        for s in sums.iter_mut() {
            s.add([0.0; 4], 0.0, cut.unaccounted * contrast);
        }
        for (i, region) in cut.visible(regions) {
            // Under the box filter a planar piece's weight is its area: where
            // the walk's merge of close vertices (a long, thin piece) gives
            // it less, the piece keeps its own colour density over its whole
            // area and the difference goes to the bound (full contrast). A
            // piece left with no weight at all takes the density of the
            // region's heaviest part, its area as the bound.
            let exact_weight = pixels[0].shading.filter == PixelFilter::Box
                && !matches!(views[i], ViewRef::Sphere(_));
            let mut heaviest: Option<([f64; 4], f64)> = None;
            let mut lost = [(0, 0.0); 4];
            let mut count = 0;
            by_column(region, left, pixels.len(), columns, |c, piece| {
                let p = &pixels[c];
                let (mut colour, mut w, mut b) =
                    shade_view(&p.shading, &views[i], piece, &p.support, &mut parts[c]);
                if exact_weight {
                    let area = piece.area();
                    if w > 0.0 && w != area {
                        colour = colour.map(|v| v * (area / w));
                        b += (area - w).abs();
                        w = area;
                    } else if w <= 0.0 && area > 0.0 {
                        // Its colour after the other parts; past the few
                        // kept, none (full contrast in the bound either way).
                        if count < lost.len() {
                            lost[count] = (c, area);
                            count += 1;
                        } else {
                            sums[c].add([0.0; 4], area, b + area);
                        }
                        return;
                    }
                }
                sums[c].add(colour, w, b);
                if heaviest.is_none_or(|(_, most)| w > most) {
                    heaviest = Some((colour, w));
                }
            });
            for &(c, area) in &lost[..count] {
                let density = match heaviest {
                    Some((colour, w)) if w > 0.0 => colour.map(|v| v / w),
                    _ => [0.0; 4],
                };
                sums[c].add(density.map(|v| v * area), area, area);
            }
        }
        for r in &cut.slivers {
            by_column(r, left, pixels.len(), columns, |c, piece| {
                // The sky at its centroid, whatever covers it: its whole
                // weight times the larger of full contrast and the sky's
                // range as the bound (at most 1e-9 of the support's).
                let Shading { filter, centre, .. } = pixels[c].shading;
                let w = filter.integral(piece, centre);
                let at = piece.centroid();
                let colour = sky(scene, &scene.camera.ray(at[0], at[1])).to_array();
                sums[c].add(colour.map(|v| f64::from(v) * w), w, w.abs() * contrast);
            });
        }
        for (r, gap) in gaps.iter() {
            // A gap the list leaves open (past the cap, or where a listed
            // primitive's edge and the ray disagree) is shown by the
            // primitive the ray through its centroid meets, as if it
            // covered the gap: its view, once for all its pieces.
            let seen = match *gap {
                Gap::Seen(id, view) => match view {
                    Some(i) => Some(views[i].clone()),
                    None => candidate_view(scene, cache, memo, id)?,
                },
                Gap::Sky | Gap::SkyAmong => None,
            };
            by_column(r, left, pixels.len(), columns, |c, piece| {
                let p = &pixels[c];
                let Shading {
                    filter,
                    centre,
                    options,
                    ..
                } = p.shading;
                let sky_over = |r: &ConvexPolygon| {
                    sky_integral(
                        scene,
                        r,
                        Whole::Unknown,
                        filter,
                        centre,
                        sky_tolerance(options),
                    )
                };
                match (gap, &seen) {
                    (Gap::Sky, _) => {
                        let (colour, w) = sky_over(piece);
                        sums[c].add(colour, w, 0.0);
                    }
                    (Gap::Seen(..), Some(view)) => {
                        // The gap's whole weight (full contrast) as the
                        // bound, and the weight of any part of it beyond
                        // that primitive's horizon (which it does not
                        // cover: its colour is not known).
                        let (colour, w, b) = match view {
                            ViewRef::Sphere(sphere) => {
                                let mut part = ConvexPolygon::empty();
                                sphere.region_into(piece, &mut part);
                                sphere.shade(&p.shading, &part, &mut parts[c])
                            }
                            _ => shade_view(&p.shading, view, piece, &p.support, &mut parts[c]),
                        };
                        let beyond = (filter.integral(piece, centre) - w).abs();
                        sums[c].add(colour, w, b + w.abs() + beyond);
                    }
                    // The sky, its whole weight as the bound: past the
                    // cap, or where the primitive met has no view.
                    (Gap::SkyAmong | Gap::Seen(..), _) => {
                        let (colour, w) = sky_over(piece);
                        sums[c].add(colour, w, w.abs());
                    }
                }
            });
        }
        Some(())
    }
}

/// Gives `shade(column, part)` the part of convex polygon `piece` in each
/// column of a row of `columns` pixels whose left side is at `left`
/// (column `c` spans `[left + c, left + c + 1)`): `piece` itself, not
/// clipped, when it lies in one column (always, for one column); else its
/// parts between the vertical lines `x = left + c`, split off left to
/// right ([`ConvexPolygon::split_into`]), those with no area skipped.
/// Parts past the row's ends (rounding) go to its end columns.
/// `buffers`: the split's.
pub(super) fn by_column(
    piece: &ConvexPolygon,
    left: f64,
    columns: usize,
    buffers: &mut [ConvexPolygon; 3],
    mut shade: impl FnMut(usize, &ConvexPolygon),
) {
    let (lo, hi) = piece.bounds();
    let last = columns.saturating_sub(1);
    // Truncation of a non-negative float is its floor (NaN: 0).
    let first = ((lo[0] - left).max(0.0) as usize).min(last);
    let end = ((hi[0] - left).ceil().max(1.0) as usize)
        .min(columns)
        .max(first + 1);
    if end - first == 1 {
        shade(first, piece);
        return;
    }
    let [rest, part, right] = buffers;
    rest.clone_from(piece);
    for c in first..end - 1 {
        // `x ≤ left + c + 1` inside.
        rest.split_into(-1.0, 0.0, left + (c + 1) as f64, part, right);
        if part.area() > 0.0 {
            shade(c, part);
        }
        std::mem::swap(rest, right);
    }
    if rest.area() > 0.0 {
        shade(end - 1, rest);
    }
}

/// `(Σ colour·k, Σ k, bound)` of the primitive of `view` over screen
/// `region` (a part of its region of `support`, the pixel's or one of
/// its quarters): a planar one's ([`shade_region`]), or a sphere's
/// ([`SphereView::shade`](super::sphere::SphereView::shade)) with the
/// weight its outline's chords leave out of the support as full contrast.
fn shade_view(
    shading: &Shading<'_>,
    view: &ViewRef<'_>,
    region: &ConvexPolygon,
    support: &ConvexPolygon,
    stats: &mut PixelStats,
) -> ([f64; 4], f64, f64) {
    match view {
        ViewRef::Sphere(sphere) => {
            let (c, w, b) = sphere.shade(shading, region, stats);
            (
                c,
                w,
                b + sphere.sliver_bound(support, shading.filter, shading.centre),
            )
        }
        _ => match view.planar() {
            Some(planar) => shade_region(shading, planar, region, None, stats),
            None => ([0.0; 4], 0.0, 0.0),
        },
    }
}

/// How far `weight`, what a pixel's regions were given, is from the pixel
/// filter's whole weight: 1, as every [`PixelFilter`] integrates to 1 over
/// its support (so nothing is integrated again per pixel).
pub(super) fn weight_error(weight: f64) -> f64 {
    (weight - 1.0).abs()
}

/// What a part of a support no listed primitive covers shows.
pub(super) enum Gap {
    /// The ray through its centroid meets nothing, nor does a mesh reach
    /// into it.
    Sky,
    /// The ray through its centroid meets nothing, but mesh triangles
    /// reach into it past [`MAX_GAP_PRIMITIVES`]: the sky, its whole
    /// weight as the bound.
    SkyAmong,
    /// The ray through its centroid meets this primitive (and its view's
    /// index, if it has one in the list).
    Seen(Seen, Option<usize>),
}

/// Buffers one thread reuses from pixel to pixel, so that the exact pixel
/// allocates nothing once they have grown to the largest neighbourhood.
#[derive(Default)]
pub(crate) struct Scratch<'a> {
    views: Vec<ViewRef<'a>>,
    /// Every primitive tried so far and its view's index (none: edge-on).
    tried: Vec<(Seen, Option<usize>)>,
    regions: Regions,
    gaps: Vec<(ConvexPolygon, Gap)>,
    cut: Cut,
    order: Order,
    planes: Vec<[f64; 4]>,
    /// The triangles [`SurfaceViews::meshes_in_gap`] lists.
    binned: Vec<(u32, u32, u32)>,
    memo: ViewMemo,
    /// The views [`Flood::spread`] added, by index.
    flooded: Vec<usize>,
    confirmed: Confirmed,
    sky_span: SkySpan,
    uniform_span: UniformSpan,
    /// The thread's screen cells (tent and Mitchell pixels share them).
    screen_cells: ScreenCells,
    /// Where [`sky_at_centre`]'s bound is surely within the tolerance
    /// (once per row: the scene and options are the frame's).
    sky_clear_above: Option<f64>,
    /// [`by_column`]'s buffers.
    columns: [ConvexPolygon; 3],
    /// [`Occluders::search`]'s buffers.
    occluders: OccluderBuffers<'a>,
    /// The row's last run [`Scratch::nothing_in_front`] found clear.
    run_clear: Option<RunClear>,
    /// The pixels of the row's last shared cut.
    pub(super) shared_cut: SharedCutFill,
}

impl<'a> Scratch<'a> {
    /// Empty buffers for a row of the frame of `cache`, with the views of
    /// mesh triangles this thread kept from its last row of that frame
    /// ([`ViewMemo`]); [`Scratch::end_row`] keeps them for its next.
    pub(crate) fn for_row(cache: &SurfaceViews) -> Scratch<'a> {
        Scratch {
            memo: ViewMemo::take_for(cache.frame),
            screen_cells: ScreenCells::take_for(cache.frame),
            ..Scratch::default()
        }
    }

    /// Ends a row: the thread keeps its views for its next row.
    pub(crate) fn end_row(self) {
        self.memo.keep();
        self.screen_cells.keep();
    }

    /// The colour of pixel `(x, y)` under `filter` whose centres in reach
    /// all see the sky, when the rectangle of its sky span ([`SkySpan`])
    /// is clear of every plane, quad and mesh triangle and the sky's value
    /// at its centre is within the tolerance ([`sky_at_centre`]):
    /// what the sky-only branch of [`exact_pixel`] gives it (the filter
    /// integrates to 1 over the support, so the mean is that value, up to
    /// the rounding of the support's integral), without building the
    /// support or testing it. `None` leaves the pixel to [`exact_pixel`]. A triangle
    /// that reaches into no part of the rectangle reaches into none of the
    /// pixel's support, which lies inside it.
    pub(crate) fn sky_pixel(
        &mut self,
        scene: &Scene,
        cache: &'a SurfaceViews,
        options: &FilterOptions,
        filter: PixelFilter,
        (x, y): (u32, u32),
    ) -> Option<Rgba> {
        if !self.sky_span.views_clear(cache, filter, (x, y)) {
            return None;
        }
        let span = &mut self.sky_span;
        let meshes_clear = match span.meshes_clear {
            Some(clear) => clear,
            None => {
                let wide = span.wide.as_ref()?;
                let clear = !cache.meshes_in(scene, wide, &mut self.planes, |_| true);
                span.meshes_clear = Some(clear);
                clear
            }
        };
        if !meshes_clear {
            return None;
        }
        let centre = [f64::from(x) + 0.5, f64::from(y) + 0.5];
        let tolerance = sky_tolerance(options);
        let clear_above = *self
            .sky_clear_above
            .get_or_insert_with(|| sky_clear_above(scene, tolerance, filter));
        let ray = scene.camera.ray(centre[0], centre[1]);
        // The support's lowest ray, as `sky_at_centre` takes it.
        let reach = std::f64::consts::SQRT_2 * filter.radius() * sky_step(scene);
        if ray.direction.y - reach >= clear_above {
            // What `sky_at_centre` gives, its bound not computed.
            return Some(mean(sky(scene, &ray).to_array().map(f64::from), 1.0));
        }
        let (c, bound) = sky_at_centre(scene, centre, filter)?;
        (bound <= tolerance).then(|| mean(c, 1.0))
    }

    /// How many pixels from `pixel` on, of the `run` whose centres in reach
    /// all see `id` (seen through `view`), have nothing in front of
    /// `view`'s plane in the rectangle their supports cover
    /// ([`in_front_within`]): the whole run where it is clear, else the
    /// longest of a quarter, a sixteenth, … of it that is, down to the
    /// pixel's own support (a sphere's box or an occluder elsewhere in a
    /// long run costs the rest of the run its spans no more than a few
    /// tests). Kept for the pixels after it. `None` when something lies in
    /// front within the pixel's own support (the general path takes it).
    pub(super) fn nothing_in_front(
        &mut self,
        pixel: &ExactPixel<'_, 'a>,
        id: Seen,
        view: &View,
        run: u32,
    ) -> Option<u32> {
        let (x, y) = pixel.at;
        if let Some(known) = &self.run_clear
            && known.id == id
            && (known.from..known.until).contains(&x)
        {
            return Some(known.until - x);
        }
        let mut len = run.max(1);
        loop {
            let rect = crate::span::span_rect(pixel.shading.filter, (x, y), len);
            let occluded = in_front_within(
                (pixel.shading.frame.scene, pixel.cache),
                id,
                &ViewRef::Frame(view),
                &rect,
                &mut self.memo,
                &mut self.planes,
                &mut self.occluders,
            );
            if !occluded {
                self.run_clear = Some(RunClear {
                    id,
                    from: x,
                    until: x.saturating_add(len),
                });
                return Some(len);
            }
            if len == 1 {
                return None;
            }
            len = (len / 4).max(1);
        }
    }

    /// Whether a sphere is among the listed views.
    pub(super) fn lists_a_sphere(&self) -> bool {
        (self.views.iter()).any(|v| matches!(v, ViewRef::Sphere(_)))
    }

    /// The colour and counters of pixel `(x, y)` when a span set up by a
    /// pixel before it in its row answers it without any work
    /// ([`UniformSpan::filled`]).
    pub(crate) fn span_fill(&self, (x, y): (u32, u32)) -> Option<&(Rgba, PixelStats)> {
        self.uniform_span.filled((x, y))
    }
}

/// A run found clear by [`Scratch::nothing_in_front`]: pixels
/// `from..until` of the row (a [`Scratch`] lives for one row) whose
/// centres in reach see `id`, with nothing in front of its plane in the
/// rectangle their supports cover.
struct RunClear {
    id: Seen,
    from: u32,
    until: u32,
}

/// The colours and counters of the pixels of a row's last shared cut.
#[derive(Default)]
pub(super) struct SharedCutFill {
    pub(super) y: u32,
    pub(super) left: u32,
    pub(super) pixels: Vec<(Rgba, PixelStats)>,
    /// Each pixel's sums and counters while the cut is shaded.
    pub(super) sums: Vec<Sums>,
    pub(super) parts: Vec<PixelStats>,
}

pub(super) fn mean(acc: [f64; 4], weight: f64) -> Rgba {
    quadtex_core::RegionIntegral {
        colour: quadtex_core::WeightedColour(acc),
        weight,
        error_bound: 0.0,
    }
    .mean()
    .unwrap_or(Rgba::TRANSPARENT)
}
