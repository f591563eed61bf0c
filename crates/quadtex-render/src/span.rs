//! Runs of magnified pixels answered once: the exact pixel's shortcut for
//! consecutive pixels of a row that lie inside one primitive, over one
//! uniform square of its texture, all lit or all in shadow.
//!
//! Under most of a ground plane near the camera a pixel's support lies
//! inside one primitive, its image inside one terminal square of the
//! texture, and the sun reaches every point of it: its exact integral is
//! that square's colour, tinted and lit, over the filter's weight. The
//! pixels of a row whose centres in reach all see the same primitive (the
//! render loop's runs, [`crate::exact::exact_pixel`]'s `run`) share all
//! three facts whenever the rectangle their supports cover has them, so
//! [`UniformSpan`] decides them once for a span of such pixels, and each
//! pixel then costs its filter weight. A span's answer is each pixel's:
//!
//! * **Inside the primitive.** The rectangle's corners inside every line
//!   of the primitive's view imply each support's corners are: the side
//!   test `a·x + b·y + c` in floats is monotone in `x` and in `y`, and the
//!   supports' corners are the same float expressions inside the rectangle
//!   (the argument of the sky's spans).
//! * **One square.** [`quadtex_core::Texture::uniform_colour_over`]: the
//!   rectangle's image lies in one terminal square, far enough in front of
//!   the horizon that the region integral takes each support as it is.
//! * **One light.** The points the pixels' shadow rays leave from (each
//!   region's centroid on the surface, lifted off it by `10⁻⁶` of its
//!   distance) lie within the surface's part under the rectangle, lifted
//!   as much; seen along the sun's direction every shadow ray is one
//!   point, so a caster whose outline along the sun misses that part's
//!   outline by more than the lift and rounding shades none of them
//!   ([`shadow_free`]). A plane is missed when the part lies wholly on
//!   the side the sun points away from. Where that cannot be shown (a
//!   mesh, or an outline in reach) each pixel takes its own shadow ray.
//!
//! A span that fails is shortened; once one of [`MIN_SPAN`] pixels fails,
//! its pixels take the general path and the next tries wait a growing
//! number of pixels ([`UniformSpan::backoff`]): where the texture is
//! minified no span holds, and the tries would only cost.

use quadtex_core::{ConvexPolygon, FilterOptions, PixelFilter, Rgba};

use crate::caster::Seen;
use crate::frame::{Frame, lit_factor};
use crate::math::Vec3;
use crate::scene::{Geometry, Lighting};
use crate::stats::PixelStats;
use crate::sun_grid::apart;
use crate::view::{Placement, View, placement};

/// Most pixels a span holds (a run of magnified pixels is seldom longer
/// than the cell it lies in; longer tries fail more often).
const MAX_SPAN: u32 = 64;

/// Fewest pixels a span is tried over.
pub(crate) const MIN_SPAN: u32 = 2;

/// Most pixels a row waits after failed tries before trying again.
const MAX_BACKOFF: u32 = 64;

/// What a span is tried against: the frame, the view of the primitive its
/// pixels' centres see, the pixel filter and the texture filter's options.
#[derive(Clone, Copy)]
pub(crate) struct SpanQuery<'q, 'f> {
    pub frame: &'q Frame<'f>,
    pub view: &'q View,
    pub filter: PixelFilter,
    pub options: &'q FilterOptions,
}

/// What every pixel of a span gets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SpanAnswer {
    /// The texture's colour over the span (linear, premultiplied; before
    /// the surface's tint), `None` when the surface is untextured.
    pub texture: Option<Rgba>,
    /// The lighting factor of every pixel's region
    /// ([`crate::frame::lambert`]'s value), `None` where each pixel takes
    /// its own shadow ray.
    pub light: Option<[f32; 3]>,
}

/// The lighting factor over all of one run of pixels (row, primitive,
/// pixels up to `until`), `None` when it is not one.
#[derive(Debug, Default)]
struct RunLight {
    row: Option<u32>,
    id: Seen,
    from: u32,
    until: u32,
    light: Option<[f32; 3]>,
}

/// The span of the row being shaded that the last pixels fell in, and
/// what the next try starts from.
#[derive(Debug, Default)]
pub(crate) struct UniformSpan {
    /// The row, `None` before the first span.
    row: Option<u32>,
    /// The primitive every centre in reach of the span's pixels sees.
    id: Seen,
    /// Pixels `from..until` of the row.
    from: u32,
    until: u32,
    /// `None`: the span failed, its pixels take the general path.
    answer: Option<SpanAnswer>,
    /// Length of the next try.
    guess: u32,
    /// Pixels the row waits after the next failure at [`MIN_SPAN`].
    backoff: u32,
    /// The light over the whole run the span lies in, tested once a run.
    run_light: RunLight,
    /// The colour and counters of the span's first pixel, when every
    /// pixel of the span comes out the same ([`UniformSpan::set_fill`]).
    fill: Option<(Rgba, PixelStats)>,
    /// Texture lookups the tries made since [`UniformSpan::take_lookups`].
    lookups: u64,
}

impl UniformSpan {
    /// What pixel `(x, y)` of a run of `run` pixels (itself and those after
    /// it in the row) whose centres in reach all see primitive `id`, seen
    /// through `query.view`, shares with its span; `None` when it takes
    /// the general path. Sets up a span at `x` when none covers it.
    pub fn answer(
        &mut self,
        query: &SpanQuery<'_, '_>,
        (x, y): (u32, u32),
        id: Seen,
        run: u32,
    ) -> Option<SpanAnswer> {
        let SpanQuery {
            frame,
            view,
            filter,
            ..
        } = *query;
        if self.row == Some(y) && self.id == id && (self.from..self.until).contains(&x) {
            return self.answer;
        }
        if self.row != Some(y) {
            self.guess = MAX_SPAN;
            self.backoff = 1;
        }
        self.row = Some(y);
        self.id = id;
        self.from = x;
        self.fill = None;
        // The sun over the whole run, once: where it lights all of it, it
        // lights every span inside.
        let run_end = x.saturating_add(run);
        let known = &self.run_light;
        if !(known.row == Some(y) && known.id == id && (known.from..known.until).contains(&x)) {
            let light = (run >= MIN_SPAN)
                .then(|| span_light(frame, view, &span_rect(filter, (x, y), run)))
                .flatten();
            self.run_light = RunLight {
                row: Some(y),
                id,
                from: x,
                until: run_end,
                light,
            };
        }
        let run_light = self.run_light.light;
        let mut len = run.min(self.guess).min(MAX_SPAN);
        loop {
            if len < MIN_SPAN {
                // Too short to share anything (or the run ends here).
                self.until = x.saturating_add(len.max(1));
                self.answer = None;
                return None;
            }
            if let Some(answer) = span_answer(query, (x, y), len, run_light, &mut self.lookups) {
                self.until = x.saturating_add(len);
                self.answer = Some(answer);
                self.guess = len.saturating_mul(2).min(MAX_SPAN);
                self.backoff = 1;
                return Some(answer);
            }
            if len == MIN_SPAN {
                // Wait a growing number of pixels before the next try.
                let wait = (MIN_SPAN + self.backoff).min(run);
                self.until = x.saturating_add(wait);
                self.answer = None;
                self.guess = MIN_SPAN;
                self.backoff = (self.backoff * 2).min(MAX_BACKOFF);
                return None;
            }
            len = (len / 4).max(MIN_SPAN);
        }
    }

    /// The lighting factor of every region inside the supports of the run
    /// of pixel `(x, y)` on primitive `id`, when one test settled it for
    /// the whole run ([`UniformSpan::answer`] tests it once a run).
    pub fn run_light(&self, (x, y): (u32, u32), id: Seen) -> Option<[f32; 3]> {
        let run = &self.run_light;
        (run.row == Some(y) && run.id == id && (run.from..run.until).contains(&x))
            .then_some(run.light)
            .flatten()
    }

    /// The texture lookups the span tries made since the last call (one
    /// a try that reached the texture): the render summary counts them
    /// as the tree queries they are.
    pub fn take_lookups(&mut self) -> u64 {
        std::mem::take(&mut self.lookups)
    }

    /// Records `colour` and `stats`, what the span's first pixel came
    /// out as, as every pixel's of the span: the caller has made sure they
    /// are (the filter's weight is the same at every pixel, and the span's
    /// light is known).
    pub fn set_fill(&mut self, colour: Rgba, stats: PixelStats) {
        self.fill = Some((colour, stats));
    }

    /// The colour and counters of pixel `(x, y)` when it lies in the span
    /// after its first pixel and the span has a fill.
    pub fn filled(&self, (x, y): (u32, u32)) -> Option<&(Rgba, PixelStats)> {
        (self.row == Some(y) && x > self.from && x < self.until)
            .then_some(self.fill.as_ref())
            .flatten()
    }
}

/// The rectangle the supports of the `len` pixels from `(x, y)` cover.
pub(crate) fn span_rect(filter: PixelFilter, (x, y): (u32, u32), len: u32) -> ConvexPolygon {
    let r = filter.radius();
    let cy = f64::from(y) + 0.5;
    let (first, last) = (
        f64::from(x) + 0.5,
        f64::from(x) + f64::from(len.max(1) - 1) + 0.5,
    );
    ConvexPolygon::rect(first - r, cy - r, last + r, cy + r)
}

/// What every pixel of the `len` pixels from `(x, y)` gets, when their
/// supports' rectangle lies inside `view`'s primitive, over one uniform
/// square of its texture (module documentation); `run_light`, when known,
/// is the light over the whole run they lie in. `lookups` counts the
/// texture lookups made.
fn span_answer(
    query: &SpanQuery<'_, '_>,
    (x, y): (u32, u32),
    len: u32,
    run_light: Option<[f32; 3]>,
    lookups: &mut u64,
) -> Option<SpanAnswer> {
    let SpanQuery {
        frame,
        view,
        filter,
        options,
    } = *query;
    let rect = span_rect(filter, (x, y), len);
    let (first, cy) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
    if !matches!(placement(&rect, view.lines()), Placement::Inside) {
        return None;
    }
    // In front of the camera at every corner (depths finite).
    if !rect
        .vertices()
        .iter()
        .all(|&s| view.depth_at(s).is_finite())
    {
        return None;
    }
    let texture = match frame.texture(view.surface()) {
        Some(texture) => {
            let pixel = filter.support([first, cy]);
            *lookups += 1;
            Some(texture.uniform_colour_over(view.projection(), &rect, &pixel, options)?)
        }
        None => None,
    };
    Some(SpanAnswer {
        texture,
        light: run_light.or_else(|| span_light(frame, view, &rect)),
    })
}

/// The lighting factor every region inside screen rectangle `rect` on
/// `view`'s primitive gets from [`crate::frame::lambert`] at its centroid,
/// when it is one (module documentation).
fn span_light(frame: &Frame<'_>, view: &View, rect: &ConvexPolygon) -> Option<[f32; 3]> {
    let scene = frame.scene;
    let Lighting::Lambert { direction, .. } = scene.lighting else {
        return Some(lit_factor(&scene.lighting, 0.0));
    };
    let cam = &scene.camera;
    // The side the camera sees the surface from, as `lambert` decides it
    // per ray (`normal · ray > 0`): the same at every corner, by a margin
    // rounding cannot cross, or left to each pixel.
    let &[a, b, c, d] = rect.vertices() else {
        return None;
    };
    let rect = [a, b, c, d];
    let normal = view.normal();
    let facing = rect.map(|[px, py]| {
        let d = cam.direction(px, py);
        normal.dot(d) / (normal.length() * d.length())
    });
    let n = if facing.iter().all(|&f| f > 1e-9) {
        -normal
    } else if facing.iter().all(|&f| f < -1e-9) {
        normal
    } else {
        return None;
    };
    // `max` takes 0 for a NaN too.
    let cos = n.dot(direction).max(0.0);
    if cos <= 0.0 {
        // Facing away from the sun: no shadow ray is cast.
        return Some(lit_factor(&scene.lighting, 0.0));
    }
    let corners = rect.map(|s| cam.position + cam.direction(s[0], s[1]) * view.depth_at(s));
    if !corners.iter().all(|p| p.is_finite()) {
        return None;
    }
    shadow_free(
        frame,
        (view.surface(), view.triangle()),
        &corners,
        direction,
    )
    .then(|| lit_factor(&scene.lighting, cos as f32))
}

/// Whether no shadow ray toward the sun (`direction`, a unit vector) from
/// a point of the convex planar polygon `corners` on surface `from` (on
/// its mesh triangle `triangle`, if it is a mesh's),
/// lifted off it by at most `10⁻⁶` of its distance from the camera plus
/// one (in any direction), meets any surface [`crate::caster::Caster::occluded_leaving`]
/// tests (module documentation); false where that is not shown.
fn shadow_free(
    frame: &Frame<'_>,
    (from, triangle): (usize, Option<u32>),
    corners: &[Vec3; 4],
    direction: Vec3,
) -> bool {
    let scene = frame.scene;
    let camera = scene.camera.position;
    let distance = corners
        .iter()
        .fold(0f64, |m, &p| m.max((p - camera).length()));
    let lift = 1.01e-6 * (1.0 + distance);
    let scale = corners
        .iter()
        .fold(1f64, |m, p| m.max(p.x.abs()).max(p.y.abs()).max(p.z.abs()));
    // Room for the lift and for rounding in the points and the casters'
    // own intersection tests.
    let margin = lift + 1e-9 * scale;
    // Two unit axes across the sun's direction: along it, a ray is a point.
    let helper = if direction.x.abs() < 0.9 {
        Vec3::new(1.0, 0.0, 0.0)
    } else {
        Vec3::new(0.0, 1.0, 0.0)
    };
    let Some(a1) = direction.cross(helper).normalized() else {
        return false;
    };
    let a2 = direction.cross(a1);
    let along = |p: Vec3| [p.dot(a1), p.dot(a2)];
    let outline = ConvexPolygon::hull(&corners.map(along));
    (scene.surfaces.iter().enumerate()).all(|(i, s)| match &s.geometry {
        Geometry::Plane { .. } | Geometry::Quad { .. } if i == from => true,
        Geometry::Plane { point, normal, .. } => {
            // The ray `p + t·direction` meets the plane at
            // `t = −m·(p − q) / (m·direction)`: never for `t > 0` when the
            // part lies wholly on the side the sun points away from.
            let toward = normal.dot(direction);
            let length = normal.length();
            toward != 0.0
                && corners.iter().all(|&p| {
                    let side = normal.dot(p - *point) / length;
                    side * toward.signum() > margin + 1e-9 * point.length()
                })
        }
        Geometry::Quad {
            origin,
            edge_u,
            edge_v,
        } => {
            let quad = [
                *origin,
                *origin + *edge_u,
                *origin + *edge_u + *edge_v,
                *origin + *edge_v,
            ]
            .map(along);
            apart(&outline, &ConvexPolygon::hull(&quad), margin)
        }
        Geometry::Sphere { centre, radius } => {
            let c = along(*centre);
            outline.edge_lines().any(|l| {
                let norm = l[0].hypot(l[1]);
                norm > 0.0 && -(l[0] * c[0] + l[1] * c[1] + l[2]) / norm > radius + margin
            })
        }
        // The mesh the rays leave: clear when its sun grid shows no other
        // triangle between the one they leave and the sun (the answer each
        // pixel's own ray would take).
        Geometry::Mesh(_) if i == from => {
            triangle.is_some_and(|t| frame.rays.clear_of_own_mesh((from, t), direction))
        }
        // Its box's outline holds every triangle's (none when the box is
        // not known).
        Geometry::Mesh(mesh) => mesh.bounds().is_some_and(|b| {
            let corners: [Vec3; 8] = std::array::from_fn(|k| {
                Vec3::new(
                    if k & 1 == 0 { b.lo.x } else { b.hi.x },
                    if k & 2 == 0 { b.lo.y } else { b.hi.y },
                    if k & 4 == 0 { b.lo.z } else { b.hi.z },
                )
            });
            apart(&outline, &ConvexPolygon::hull(&corners.map(along)), margin)
        }),
    })
}
