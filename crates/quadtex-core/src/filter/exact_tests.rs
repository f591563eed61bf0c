//! Tests of the exact filter's scans, sweeps and bands.

use crate::filter::few_cells::FewCells;
use crate::filter::pixel_filter::PixelFilter;
use crate::filter::projection::{Mat3, adjugate, apply};
use crate::filter::scan::{
    BAND_VERTICES, BandBuffer, Bands, LeftOf, band_left_of, band_to_screen, scan_grid, shoelace,
};
use crate::filter::tiles::tile_map;
use crate::filter::walk::box_diagonal;
use crate::filter::wrap::WrapMode;
use crate::geometry::polygon::ConvexPolygon;
use crate::geometry::polygon::bounds_of;
use crate::tree::unit_side;

/// A convex polygon of `n` vertices on an ellipse, counter-clockwise
/// or (`reversed`) clockwise, vertices at random angles.
fn ellipse_polygon(next: &mut impl FnMut() -> f64, n: usize, reversed: bool) -> Vec<[f64; 2]> {
    let (cx, cz) = (next() * 4.0 - 2.0, next() * 4.0 - 2.0);
    let (rx, rz) = (0.1 + next() * 3.0, 0.1 + next() * 3.0);
    let mut angles: Vec<f64> = (0..n).map(|_| next() * std::f64::consts::TAU).collect();
    angles.sort_by(f64::total_cmp);
    let mut p: Vec<[f64; 2]> = angles
        .iter()
        .map(|a| [cx + rx * a.cos(), cz + rz * a.sin()])
        .collect();
    if reversed {
        p.reverse();
    }
    p
}

/// The sweep's area left of each cut is the clip's (the slow
/// reference), for increasing cuts before, across (on vertices too)
/// and past random convex polygons in either orientation, under mild
/// random perspective: polygons with vertical sides at the cuts, the
/// bands `scan_grid` cuts (an ellipse between two lines), and a vertex
/// rounding left a few ulps behind its predecessor.
#[test]
fn the_sweep_gives_each_cut_what_clipping_gives() {
    let mut next = crate::test_rng::uniform(29);
    let mut checked = 0;
    for case in 0..3000 {
        let n = 3 + case % 10;
        let mut texture = ellipse_polygon(&mut next, n, case % 2 == 1);
        match case % 5 {
            // An axis-aligned box: vertical sides, cut exactly on them.
            0 => {
                let (x0, z0) = (next() * 2.0, next() * 2.0);
                let (x1, z1) = (x0 + 0.25 * (1 + case % 7) as f64, z0 + next() + 0.1);
                texture = vec![[x0, z0], [x1, z0], [x1, z1], [x0, z1]];
            }
            // A band of the ellipse between two lines z = const.
            1 => {
                let p = ConvexPolygon::new(&texture);
                if let Ok(p) = p {
                    let (lo, hi) = p.bounds();
                    let z = lo[1] + (hi[1] - lo[1]) * next();
                    let band = p.clip(0.0, 1.0, -z).clip(0.0, -1.0, z + 0.3);
                    if band.vertices().len() >= 3 {
                        texture = band.vertices().to_vec();
                    }
                }
            }
            // A vertex a few ulps behind its predecessor in x.
            2 => {
                let i = case % texture.len();
                let behind = texture[i][0] - 4.0 * f64::EPSILON * texture[i][0].abs();
                texture.insert(i + 1, [behind, texture[i][1]]);
            }
            _ => {}
        }
        // Mild perspective: w stays within [0.5, 1.5] over the polygon.
        let m: Mat3 = [
            [1.0 + next(), next() - 0.5, next() * 10.0],
            [next() - 0.5, 1.0 + next(), next() * 10.0],
            [0.1 * (next() - 0.5), 0.1 * (next() - 0.5), 1.0],
        ];
        let centre = [next() * 10.0, next() * 10.0];
        let screen = band_to_screen(&texture, &m, centre);
        let total = shoelace(&screen);
        let mut sweep = LeftOf::new(&texture, &screen, total);
        let xs: Vec<f64> = texture.iter().map(|t| t[0]).collect();
        let (lo, hi) = (
            xs.iter().copied().fold(f64::INFINITY, f64::min),
            xs.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        );
        // Cuts: before, on every vertex, between, past.
        let mut cuts: Vec<f64> = xs.clone();
        cuts.extend((0..8).map(|_| lo - 0.5 + (hi - lo + 1.0) * next()));
        cuts.extend([lo - 1.0, lo, hi, hi + 1.0]);
        cuts.sort_by(f64::total_cmp);
        for cut in cuts {
            let swept = sweep.area(cut, &m, centre);
            let clipped = band_left_of(&texture, &screen, cut, &m, centre);
            let tolerance = 1e-11 * total.abs().max(1.0);
            assert!(
                (swept - clipped).abs() <= tolerance,
                "case {case}: cut {cut} of {texture:?}: swept {swept}, clipped {clipped}"
            );
            checked += 1;
        }
    }
    assert!(checked > 30_000);
}

/// A random map from texture to screen under which `w` stays within
/// `[0.8, 1.2]` over `region`: a rotation-shear of about unit scale, a
/// shift of up to 10 and a mild perspective.
fn mild_perspective(next: &mut impl FnMut() -> f64, region: &ConvexPolygon) -> Mat3 {
    let (lo, hi) = region.bounds();
    let g = 0.2 / (1.0 + lo[0].abs().max(hi[0].abs()) + lo[1].abs().max(hi[1].abs()));
    [
        [1.0 + next(), next() - 0.5, next() * 10.0],
        [next() - 0.5, 1.0 + next(), next() * 10.0],
        [g * (next() - 0.5), g * (next() - 0.5), 1.0],
    ]
}

/// `(Σ colour·area, Σ area, cells)` over the cells of size `h` that
/// `region` crosses: each cell's piece clipped, mapped by `m` and
/// weighted by its screen area (relative to `centre`).
fn clip_every_cell(
    region: &ConvexPolygon,
    m: &Mat3,
    h: f64,
    centre: [f64; 2],
    colour: impl Fn(i64, i64) -> Option<[f64; 4]>,
) -> ([f64; 4], f64, f64) {
    weigh_every_cell(PixelFilter::Box, region, m, h, centre, colour)
}

/// [`clip_every_cell`] under `filter` centred at `centre`, each piece's
/// image weighed by [`PixelFilter::integral_by_cells`] (the filter's
/// cells clipped too: the slow reference of the Green's-theorem sums).
fn weigh_every_cell(
    filter: PixelFilter,
    region: &ConvexPolygon,
    m: &Mat3,
    h: f64,
    centre: [f64; 2],
    colour: impl Fn(i64, i64) -> Option<[f64; 4]>,
) -> ([f64; 4], f64, f64) {
    let (lo, hi) = region.bounds();
    let (mut sum, mut weight, mut cells) = ([0.0; 4], 0.0, 0.0);
    for z in (lo[1] / h).floor() as i64..(hi[1] / h).ceil() as i64 {
        for x in (lo[0] / h).floor() as i64..(hi[0] / h).ceil() as i64 {
            let (x0, z0) = (x as f64 * h, z as f64 * h);
            let piece = region.clip_rect(x0, z0, x0 + h, z0 + h);
            if piece.is_empty() {
                continue;
            }
            let w = filter.integral_by_cells(&piece.map(|t| apply(m, t)), centre);
            for (s, c) in sum.iter_mut().zip(colour(x, z).unwrap()) {
                *s += c * w;
            }
            weight += w;
            cells += 1.0;
        }
    }
    (sum, weight, cells)
}

/// The box scan (a band at a time, a sweep a band) gives what clipping
/// every cell gives (the slow reference, `clip_every_cell`): random
/// convex polygons in either orientation under random perspective, on
/// grids of random colours;
/// boxes with their sides on grid lines, bands of an ellipse between
/// two grid lines, triangles with their vertices on grid points;
/// negative coordinates; cells from 1/16 to 2; needles across and
/// along the grid (both of the scan's orientations).
/// A run of vertices on a cut, one chain's, with the polygon's top a
/// rounding above it (a mapped region's top edge, from the terrain
/// scene): each stays the band's, and the bands keep the region's
/// weight, in either orientation and with the axes swapped.
#[test]
fn a_cut_above_the_whole_region_ends_its_walk() {
    // Callers cut strictly below the region's top; a cut at or above
    // every vertex (a cell side whose multiples round up) must still
    // end, with no more than the buffer's vertices.
    let square = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    let m: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for top in [1.0, 2.0] {
        let mut bands = Bands::new(&square, &square);
        let mut band = BandBuffer::default();
        bands.next_band(0.5, &m, [0.0, 0.0], &mut band);
        assert_eq!(band.len(), 4);
        bands.next_band(top, &m, [0.0, 0.0], &mut band);
        assert!(band.len() <= BAND_VERTICES);
    }
}

#[test]
fn a_run_of_vertices_on_a_cut_stays_in_its_band() {
    let cases: [(&[[f64; 2]], f64); 2] = [
        (
            &[
                [0.5968829885663551, 0.7498363903052521],
                [0.5968368329422433, 0.7500000000000001],
                [0.5967517636501981, 0.75],
                [0.5966666936874391, 0.75],
            ],
            1.0 / 1024.0,
        ),
        (
            &[
                [0.1, 0.3],
                [0.9, 0.5000000000000001],
                [0.6, 0.5],
                [0.2, 0.5],
            ],
            0.25,
        ),
    ];
    let m: Mat3 = [[1.2, 0.1, 3.0], [-0.2, 0.9, 1.0], [0.01, 0.02, 1.0]];
    let colour = |x: i64, z: i64| Some([x.rem_euclid(3) as f64, z.rem_euclid(2) as f64, 1.0, 1.0]);
    let mut checked = 0;
    for (vertices, h) in cases {
        for (reversed, swapped) in [(false, false), (true, false), (false, true), (true, true)] {
            let mut v: Vec<[f64; 2]> = vertices.to_vec();
            if swapped {
                v.iter_mut().for_each(|p| p.swap(0, 1));
            }
            if reversed {
                v.reverse();
            }
            let region = ConvexPolygon::from_trusted(&v);
            // Shoelace sums relative to a point near the region, as a
            // pixel's centre is.
            let centre = apply(&m, v[0]);
            let clipped = clip_every_cell(&region, &m, h, centre, colour);
            let swept =
                scan_grid(&region, &m, h, PixelFilter::Box, centre, 4096.0, colour).unwrap();
            // The reference's clips round too: at the first case's
            // thin corner it is off by 3e-6 of that cell's weight
            // (against exact rational arithmetic, which the scan meets
            // to 2e-11). A vertex lost loses a third of the region.
            let tolerance = 1e-5 * clipped.1;
            assert!(
                (swept.1 - clipped.1).abs() <= tolerance
                    && (0..4).all(|c| (swept.0[c] - clipped.0[c]).abs() <= tolerance),
                "{v:?}: {swept:?} against {clipped:?}"
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 8);
}

/// Two or four cells (two a side) of a tile, repeated or mirrored, at
/// grid sides from 1/2 to 1/64: the region's integral from
/// [`FewCells::integrate`] (one clip a grid line, on the screen) is
/// what clipping the region to each cell in texture space and
/// integrating the piece's image gives (the slow reference), under
/// each pixel filter, for random convex regions inside the cells under
/// random perspective, regions on one side of the line (the box
/// reaches the other cell by rounding) and regions with an edge on
/// it.
#[test]
fn few_cells_give_what_clipping_every_cell_gives() {
    let mut next = crate::test_rng::uniform(37);
    let mut checked = [0; 3];
    for case in 0..3000 {
        let depth = 1 + case % 6;
        let h = unit_side(depth as u8);
        let n = 1i64 << depth;
        let (wide, tall) = match case % 3 {
            0 => (2, 1),
            1 => (1, 2),
            _ => (2, 2),
        };
        let x0 = ((next() * (n - wide + 1) as f64) as i64).min(n - wide);
        let z0 = ((next() * (n - tall + 1) as f64) as i64).min(n - tall);
        let (x1, z1) = (x0 + wide, z0 + tall);
        let tile = |i: i64| match (case / 3) % 2 {
            0 => tile_map(WrapMode::Repeat, i),
            _ => tile_map(WrapMode::Mirror, i),
        };
        let frame = [
            tile((next() * 5.0) as i64 - 2),
            tile((next() * 5.0) as i64 - 2),
        ];
        // A random convex region in local coordinates, inside the
        // cells' rectangle; or one side of it; or a rectangle with a
        // side on the grid line.
        let (rx0, rz0, rx1, rz1) = (x0 as f64 * h, z0 as f64 * h, x1 as f64 * h, z1 as f64 * h);
        let ellipse = ellipse_polygon(&mut next, 3 + case % 8, case % 2 == 1);
        let Ok(e) = ConvexPolygon::new(&ellipse) else {
            continue;
        };
        let (elo, ehi) = e.bounds();
        let fit = |[x, z]: [f64; 2]| {
            [
                rx0 + (x - elo[0]) / (ehi[0] - elo[0]) * (rx1 - rx0),
                rz0 + (z - elo[1]) / (ehi[1] - elo[1]) * (rz1 - rz0),
            ]
        };
        let local = match (case / 6) % 4 {
            0 | 1 => e.map(fit),
            2 => e.map(fit).clip_rect(rx0, rz0, rx0 + h, rz1),
            _ => ConvexPolygon::new(&[
                [rx0 + h * 0.3, rz0 + h * 0.2],
                [rx0 + h, rz0 + h * 0.2],
                [rx0 + h, rz1 - h * 0.1],
                [rx0 + h * 0.3, rz1 - h * 0.1],
            ])
            .unwrap(),
        };
        if local.is_empty() {
            continue;
        }
        let to_texture =
            |[x, z]: [f64; 2]| [frame[0].0 * x + frame[0].1, frame[1].0 * z + frame[1].1];
        let texture_region = local.map_counter_clockwise(to_texture);
        // Perspective over the region's texture box, w within [0.7, 1.3].
        let (tlo, thi) = texture_region.bounds();
        let extent = tlo.iter().chain(&thi).fold(1.0f64, |a, v| a.max(v.abs()));
        let g = 0.3 / (2.0 * extent);
        let scale = 1.0 / h * (0.5 + 2.0 * next());
        let screen_from_texture: Mat3 = [
            [
                scale * (1.0 + next()),
                scale * (next() - 0.5),
                next() * 10.0,
            ],
            [
                scale * (next() - 0.5),
                scale * (1.0 + next()),
                next() * 10.0,
            ],
            [g * (next() - 0.5), g * (next() - 0.5), 1.0],
        ];
        let texture_from_screen = adjugate(&screen_from_texture).0;
        let screen = texture_region.map_counter_clockwise(|t| apply(&screen_from_texture, t));
        let mut colours = [[[0.0; 4]; 2]; 2];
        for c in colours.iter_mut().flatten() {
            *c = [next(), next(), next(), 0.5 + 0.5 * next()];
        }
        let few = FewCells::new(frame, h, (x0, x1), (z0, z1), colours);
        let centre = {
            let c = screen.centroid();
            [c[0] + next() - 0.5, c[1] + next() - 0.5]
        };
        let filter = [PixelFilter::Box, PixelFilter::Tent, PixelFilter::Mitchell][case % 7 % 3];
        // The reference: each cell's piece in local coordinates, mapped
        // to the screen and integrated.
        let (mut want, mut want_weight) = ([0.0; 4], 0.0);
        for (cz, z) in (z0..z1).enumerate() {
            for (cx, x) in (x0..x1).enumerate() {
                let (px, pz) = (x as f64 * h, z as f64 * h);
                let piece = local.clip_rect(px, pz, px + h, pz + h);
                if piece.is_empty() {
                    continue;
                }
                let on_screen =
                    piece.map_counter_clockwise(|l| apply(&screen_from_texture, to_texture(l)));
                let w = filter.integral(&on_screen, centre);
                for (a, c) in want.iter_mut().zip(colours[cz][cx]) {
                    *a += c * w;
                }
                want_weight += w;
            }
        }
        let total = filter.integral(&screen, centre);
        let (got, weight, cells) = few
            .integrate(&screen, &texture_from_screen, filter, centre, total)
            .unwrap_or_else(|| panic!("case {case}: no lines"));
        assert_eq!(cells, (wide * tall) as f64);
        let tolerance = 1e-11 * (1.0 + screen.area());
        assert!(
            (weight - want_weight).abs() <= tolerance,
            "case {case}: weight {weight} against {want_weight}"
        );
        for c in 0..4 {
            assert!(
                (got[c] - want[c]).abs() <= tolerance,
                "case {case}: channel {c}: {} against {} ({filter:?}, {wide}×{tall}, frame {frame:?})",
                got[c],
                want[c]
            );
        }
        checked[case % 3] += 1;
    }
    assert!(checked.iter().all(|&c| c > 500), "{checked:?}");
}

#[test]
fn the_box_scan_gives_what_clipping_every_cell_gives() {
    let mut next = crate::test_rng::uniform(31);
    let (mut checked, mut transposed, mut cells) = (0, 0, 0.0);
    for case in 0..4000 {
        let n = 3 + case % 10;
        let mut texture = ellipse_polygon(&mut next, n, case % 2 == 1);
        let h = [0.0625, 0.25, 0.5, 1.0, 2.0][case % 5];
        match case % 7 {
            0 => {
                let (x0, z0) = (
                    (next() * 8.0 - 4.0).floor() * h,
                    (next() * 8.0).floor() * -h,
                );
                let (x1, z1) = (
                    // `case % 7` is 0 here: widths from the case's other digits.
                    x0 + h * (1 + (case / 7) % 6) as f64,
                    z0 + h * (1 + (case / 42) % 3) as f64,
                );
                texture = vec![[x0, z0], [x1, z0], [x1, z1], [x0, z1]];
            }
            1 => {
                if let Ok(p) = ConvexPolygon::new(&texture) {
                    let (lo, hi) = p.bounds();
                    let z = ((lo[1] + (hi[1] - lo[1]) * next()) / h).floor() * h;
                    let band = p.clip(0.0, 1.0, -z).clip(0.0, -1.0, z + h);
                    if band.vertices().len() >= 3 {
                        texture = band.vertices().to_vec();
                    }
                }
            }
            2 => {
                let mut grid_point = || {
                    [
                        (next() * 12.0 - 6.0).floor() * h,
                        (next() * 12.0 - 6.0).floor() * h,
                    ]
                };
                texture = vec![grid_point(), grid_point(), grid_point()];
            }
            // A needle: long along one axis, thin across it.
            3 => {
                let (x, z, long, thin) = (
                    next() * 4.0 - 2.0,
                    next() * 4.0 - 2.0,
                    2.0 + 6.0 * next(),
                    0.05 + 0.3 * next(),
                );
                texture = if next() < 0.5 {
                    vec![
                        [x, z],
                        [x + thin, z + 0.1],
                        [x + thin * 1.5, z + long],
                        [x - 0.1 * thin, z + long * 0.9],
                    ]
                } else {
                    vec![
                        [x, z],
                        [x + long, z - 0.1],
                        [x + long * 0.9, z + thin],
                        [x + 0.05, z + thin * 1.2],
                    ]
                };
            }
            _ => {}
        }
        let Ok(region) = ConvexPolygon::new(&texture) else {
            continue;
        };
        if region.is_empty() {
            continue;
        }
        let (lo, hi) = region.bounds();
        let m = mild_perspective(&mut next, &region);
        let centre = [next() * 10.0, next() * 10.0];
        let salt = (next() * 1e6) as i64;
        let colour = |x: i64, z: i64| {
            let k = (x * 7 + z * 13 + salt).rem_euclid(5) as f64;
            Some([k / 4.0, x.rem_euclid(2) as f64, 0.5, 1.0 - k / 8.0])
        };
        let max_cells = 4096.0;
        let clipped = clip_every_cell(&region, &m, h, centre, colour);
        if clipped.2 > max_cells {
            continue;
        }
        let swept = scan_grid(&region, &m, h, PixelFilter::Box, centre, max_cells, colour)
            .unwrap_or_else(|| panic!("case {case}: no box scan of {texture:?}"));
        let screen = region.map(|t| apply(&m, t));
        let d = box_diagonal(bounds_of(screen.vertices()));
        let scale = d * (d + 1.0);
        let tolerance = 1e-12 * scale * (1.0 + clipped.2);
        assert!(
            (swept.1 - clipped.1).abs() <= tolerance,
            "case {case}: weight {} against {} over {texture:?}",
            swept.1,
            clipped.1
        );
        for c in 0..4 {
            assert!(
                (swept.0[c] - clipped.0[c]).abs() <= tolerance,
                "case {case}: channel {c}: {} against {} over {texture:?}, h {h}",
                swept.0[c],
                clipped.0[c]
            );
        }
        if (hi[0] - lo[0]) < (hi[1] - lo[1]) {
            transposed += 1;
        }
        checked += 1;
        cells += clipped.2;
    }
    assert!(
        checked > 3000 && transposed > 500 && cells > 50_000.0,
        "{checked} cases, {transposed} transposed, {cells} cells"
    );
}

/// The tent's and Mitchell's scans (a sweep of Green's-theorem terms a
/// band, each crossed edge grown cut by cut) give what clipping every
/// cell and every filter cell gives (the slow reference,
/// [`weigh_every_cell`]): random convex polygons in either orientation
/// under random perspective, a few pixels across, centred on the
/// filter's support, across it and beside it, on grids from 1/16 to 1
/// of a texture unit.
#[test]
fn the_tent_and_mitchell_scans_give_what_clipping_every_cell_gives() {
    let mut next = crate::test_rng::uniform(47);
    let mut checked = [0usize; 2];
    let mut inside = 0;
    for case in 0..1200 {
        let filter = [PixelFilter::Tent, PixelFilter::Mitchell][case % 2];
        let n = 3 + case % 9;
        let texture = ellipse_polygon(&mut next, n, case % 3 == 1);
        let h = [0.0625, 0.125, 0.25, 0.5, 1.0][case % 5];
        let Ok(region) = ConvexPolygon::new(&texture) else {
            continue;
        };
        if region.is_empty() {
            continue;
        }
        let m = mild_perspective(&mut next, &region);
        // The filter's centre near a vertex's image: supports inside the
        // region, across its edges and off it.
        let v = apply(&m, texture[case % n]);
        let centre = [v[0] + 3.0 * next() - 1.5, v[1] + 3.0 * next() - 1.5];
        let colour = |x: i64, z: i64| {
            let k = (x * 7 + z * 13).rem_euclid(5) as f64;
            Some([k / 4.0, x.rem_euclid(2) as f64, 0.5, 1.0 - k / 8.0])
        };
        let clipped = weigh_every_cell(filter, &region, &m, h, centre, colour);
        let Some(swept) = scan_grid(&region, &m, h, filter, centre, 4096.0, colour) else {
            continue;
        };
        let tolerance = 1e-11 * (1.0 + clipped.2);
        assert!(
            (swept.1 - clipped.1).abs() <= tolerance,
            "case {case}, {filter:?}: weight {} against {} over {texture:?}",
            swept.1,
            clipped.1
        );
        for c in 0..4 {
            assert!(
                (swept.0[c] - clipped.0[c]).abs() <= tolerance,
                "case {case}, {filter:?}: channel {c}: {} against {} over {texture:?}",
                swept.0[c],
                clipped.0[c]
            );
        }
        checked[case % 2] += 1;
        if clipped.1.abs() > 0.1 {
            inside += 1;
        }
    }
    assert!(
        checked.iter().all(|&c| c > 500) && inside > 400,
        "{checked:?} cases, {inside} of weight above 0.1"
    );
}
