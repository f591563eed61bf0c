#![allow(clippy::unwrap_used)]
use super::*;
use quadtex_core::Adjustable;
use quadtex_core::Fragment;

/// The packed alpha integral over the unit square (the root colour,
/// within one 16-bit step) of an SVG 100 units wide.
fn coverage(svg: &str) -> f64 {
    let art = parse_svg(
        svg.as_bytes(),
        Path::new("t.svg"),
        &SvgOptions::at_level(8).with_limits(Limits::default()),
    )
    .unwrap();
    let options = VectorOptions {
        max_level: 8,
        ..VectorOptions::default()
    };
    let (tree, _) = QuadTree::from_vector(&art, &options).unwrap();
    let f = Fragment::new(0.0, 0.0, 1.0, 1.0).unwrap();
    tree.weighted_colour(&f, 8).0[3]
}

/// A circle flattened to a stated tolerance, packed with contour
/// leaves: where its edge crosses a small fragment, the covered area
/// is within `tolerance × arc length` of the true circle's (and, for a
/// coarse tolerance, visibly not the true one).
#[test]
fn curves_are_flattened_to_the_stated_tolerance() {
    let svg = r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 100 100"><circle cx="50" cy="50" r="40"/></svg>"#;
    let (r, w) = (0.4, 0.004);
    let f = Fragment::new(0.5 - w, 0.1 - w, 0.5 + w, 0.1 + w).unwrap();
    // The true circle's area in the fragment (its edge nearly level
    // there): ∫ (z1 − max(z0, 0.5 − √(r² − (x − 0.5)²))) dx, Simpson.
    let n = 20_000;
    let inside = |x: f64| f.z1() - f.z0().max(0.5 - (r * r - (x - 0.5) * (x - 0.5)).sqrt());
    let h = (f.x1() - f.x0()) / f64::from(n);
    let mut truth = inside(f.x0()) + inside(f.x1());
    for i in 1..n {
        truth += inside(f.x0() + f64::from(i) * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
    }
    truth *= h / 3.0;
    for tolerance in [1e-6, 1e-3] {
        let art = parse_svg(
            svg.as_bytes(),
            Path::new("c.svg"),
            &SvgOptions::default().with_curve_tolerance(tolerance),
        )
        .unwrap();
        assert_eq!(art.curve_tolerance(), Some(tolerance));
        let options = VectorOptions {
            max_level: 20,
            contour_leaves: Some(16),
            ..VectorOptions::default()
        };
        let (tree, _) = QuadTree::from_vector(&art, &options).unwrap();
        assert_eq!(
            tree.contour_leaves().unwrap().curve_tolerance(),
            Some(tolerance)
        );
        let got = tree.weighted_colour(&f, u8::MAX).0[3];
        let bound = tolerance * 2.0 * w * 1.01;
        assert!(
            (got - truth).abs() <= bound,
            "{tolerance}: {got} vs {truth}, bound {bound}"
        );
        if tolerance >= 1e-3 {
            assert!((got - truth).abs() > 0.01 * bound, "{got} vs {truth}");
        }
    }
    let refused = parse_svg(
        svg.as_bytes(),
        Path::new("c.svg"),
        &SvgOptions::default().with_curve_tolerance(1e-13),
    );
    assert!(refused.unwrap_err().to_string().contains("curve tolerance"));
}

#[test]
fn clip_paths_cut_exact_areas() {
    let head = r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 100 100">"#;
    // A 60×60 square clipped by a 20×50 rectangle moved by the clip
    // path's own transform: 20×40 remain.
    let moved = format!(
        r#"{head}<clipPath id="c"><rect x="0" y="0" width="20" height="50"
        transform="translate(30 40)"/></clipPath>
        <rect x="20" y="20" width="60" height="60" clip-path="url(#c)"/></svg>"#
    );
    assert!(
        (coverage(&moved) - 0.08).abs() < 2e-5,
        "{}",
        coverage(&moved)
    );
    // objectBoundingBox units: the left half of the square's box.
    let bbox = format!(
        r#"{head}<clipPath id="c" clipPathUnits="objectBoundingBox">
        <rect x="0" y="0" width="0.5" height="1"/></clipPath>
        <rect x="20" y="20" width="60" height="60" clip-path="url(#c)"/></svg>"#
    );
    assert!((coverage(&bbox) - 0.18).abs() < 2e-5, "{}", coverage(&bbox));
    // A clip path clipped by another: two overlapping bands leave 20×20.
    let nested = format!(
        r#"{head}<clipPath id="a"><rect x="0" y="40" width="100" height="20"/></clipPath>
        <clipPath id="b" clip-path="url(#a)"><rect x="40" y="0" width="20" height="100"/></clipPath>
        <rect x="0" y="0" width="100" height="100" clip-path="url(#b)"/></svg>"#
    );
    assert!(
        (coverage(&nested) - 0.04).abs() < 2e-5,
        "{}",
        coverage(&nested)
    );
    // clip-rule evenodd on a doubled square cuts the whole square away.
    let evenodd = format!(
        r#"{head}<clipPath id="c"><path clip-rule="evenodd"
        d="M10 10h50v50h-50z M10 10h50v50h-50z"/></clipPath>
        <rect x="0" y="0" width="100" height="100" clip-path="url(#c)"/></svg>"#
    );
    assert!(coverage(&evenodd).abs() < 2e-5, "{}", coverage(&evenodd));
}

#[test]
fn patterns_tile_exactly() {
    // Black 10×10 squares every 20 units, filling 5..95 on both axes:
    // 45 units a side are black, 0.2025 of the square.
    let svg = r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 100 100">
        <pattern id="p" width="20" height="20" patternUnits="userSpaceOnUse">
        <rect width="10" height="10"/></pattern>
        <rect x="5" y="5" width="90" height="90" fill="url(#p)"/></svg>"#;
    assert!((coverage(svg) - 0.2025).abs() < 2e-5, "{}", coverage(svg));
    // Half opacity fades the whole pattern.
    let faded = svg.replace(r#"fill="url(#p)""#, r#"fill="url(#p)" fill-opacity="0.5""#);
    assert!(
        (coverage(&faded) - 0.10125).abs() < 2e-5,
        "{}",
        coverage(&faded)
    );
}

#[test]
fn multiply_blends_encoded_colours_exactly() {
    // Opaque #808080 multiplied onto opaque #ff4000 over the whole square:
    // encoded (0.502·1, 0.502·0.251, 0), decoded.
    let svg = r##"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 10 10">
        <rect width="10" height="10" fill="#ff4000"/>
        <rect width="10" height="10" fill="#808080" style="mix-blend-mode:multiply"/></svg>"##;
    let art = parse_svg(
        svg.as_bytes(),
        Path::new("t.svg"),
        &SvgOptions::at_level(2).with_limits(Limits::default()),
    )
    .unwrap();
    let (tree, _) = QuadTree::from_vector(&art, &VectorOptions::default()).unwrap();
    let f = Fragment::new(0.0, 0.0, 1.0, 1.0).unwrap();
    let got = tree.weighted_colour(&f, 0).0;
    let g = 128.0 / 255.0;
    let want = [g, g * 64.0 / 255.0, 0.0].map(quadtex_core::srgb_decode);
    for k in 0..3 {
        assert!(
            (got[k] - want[k]).abs() < 2e-5,
            "channel {k}: {} vs {}",
            got[k],
            want[k]
        );
    }
}

/// A 2×2 PNG: red, green / blue, white.
const PNG_2X2: &str = "iVBORw0KGgoAAAANSUhEUgAAAAIAAAACCAIAAAD91JpzAAAAEklEQVR4nGP4z8DAAMIM/4EAAB/uBfsL2WiLAAAAAElFTkSuQmCC";

#[test]
fn an_embedded_image_packs_to_its_exact_texel_means() {
    let svg = format!(
        r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 10 10">
        <image width="10" height="10" href="data:image/png;base64,{PNG_2X2}"/></svg>"#
    );
    let art = parse_svg(
        svg.as_bytes(),
        Path::new("t.svg"),
        &SvgOptions::at_level(4).with_limits(Limits::default()),
    )
    .unwrap();
    let (tree, report) = QuadTree::from_vector(
        &art,
        &VectorOptions {
            max_level: 4,
            ..VectorOptions::default()
        },
    )
    .unwrap();
    assert_eq!(report.max_mean_error, 0.0);
    // Texture z is up: the top-left quadrant is texel (0, 0), red.
    let mean = |x0: f64, z0: f64| {
        let f = Fragment::new(x0, z0, x0 + 0.5, z0 + 0.5).unwrap();
        tree.weighted_colour(&f, 4).0.map(|v| v / 0.25)
    };
    let quadrant = mean;
    let close = |a: [f64; 4], b: [f64; 4]| (0..4).all(|k| (a[k] - b[k]).abs() < 1e-4);
    assert!(
        close(quadrant(0.0, 0.5), [1.0, 0.0, 0.0, 1.0]),
        "{:?}",
        quadrant(0.0, 0.5)
    );
    assert!(close(quadrant(0.5, 0.5), [0.0, 1.0, 0.0, 1.0]));
    assert!(close(quadrant(0.0, 0.0), [0.0, 0.0, 1.0, 1.0]));
    assert!(close(quadrant(0.5, 0.0), [1.0, 1.0, 1.0, 1.0]));
    // A square across the centre: a quarter of each texel.
    assert!(
        close(mean(0.25, 0.25), [0.5, 0.5, 0.5, 1.0]),
        "{:?}",
        mean(0.25, 0.25)
    );
}

#[test]
fn image_copies_beyond_the_texel_limit_are_refused() {
    // The pattern is laid out over 5 × 5 tiles (the shape's edges touch
    // a fifth row and column), each drawing the 2×2 image: 100 texels.
    let svg = format!(
        r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 8 8">
        <pattern id="p" width="2" height="2" patternUnits="userSpaceOnUse">
          <image width="2" height="2" href="data:image/png;base64,{PNG_2X2}"/></pattern>
        <rect width="8" height="8" fill="url(#p)"/></svg>"#
    );
    let limits = Limits {
        max_svg_image_texels: 99,
        ..Limits::default()
    };
    let e = parse_svg(
        svg.as_bytes(),
        Path::new("t.svg"),
        &SvgOptions::at_level(4).with_limits(limits),
    )
    .unwrap_err();
    assert!(e.to_string().contains("max_svg_image_texels"), "{e}");
    let limits = Limits {
        max_svg_image_texels: 100,
        ..Limits::default()
    };
    assert!(
        parse_svg(
            svg.as_bytes(),
            Path::new("t.svg"),
            &SvgOptions::at_level(4).with_limits(limits)
        )
        .is_ok()
    );
}

#[test]
fn images_that_cannot_be_drawn_are_errors_naming_them() {
    let parse = |body: &str| {
        let svg =
            format!(r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 10 10">{body}</svg>"#);
        parse_svg(
            svg.as_bytes(),
            Path::new("t.svg"),
            &SvgOptions::at_level(4).with_limits(Limits::default()),
        )
        .unwrap_err()
        .to_string()
    };
    let e = parse(r#"<image href="missing.png" width="10" height="10"/>"#);
    assert!(
        e.contains("t.svg") && e.contains("image \"missing.png\" could not be read"),
        "{e}"
    );
    let e = parse(r#"<image href="https://example.com/a.png" width="10" height="10"/>"#);
    assert!(e.contains("is remote"), "{e}");
    let e = parse(
        r#"<image id="anim" width="10" height="10" href="data:image/gif;base64,R0lGODlhAQABAIAAAP///wAAACH5BAEAAAAALAAAAAABAAEAAAICRAEAOw=="/>"#,
    );
    assert!(e.contains("unsupported: image in GIF format"), "{e}");
    let e =
        parse(r#"<image width="10" height="10" href="data:image/png;base64,iVBORw0KGgoAAAA"/>"#);
    assert!(e.contains("t.svg"), "{e}");
    // Found by the SVG fuzz target: a PNG header claiming 8 × 2³¹ + 2
    // texels (its CRC right), placed by a malformed `preserveAspectRatio`,
    // made usvg 0.49 panic.
    let e = parse(
        r#"<image x="0" y="1" width="18" height="18" preserveAspectRatio="xMidYMx2 slice" href="data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAiAAAACCAIAAACMowr1AAAAC0lEQVR4nGNggAEAAAoAAX+AdF4AAAAASUVORK5CYII="/>"#,
    );
    assert!(
        e.contains("t.svg") && e.contains("max_dimension") && e.contains("2147483650"),
        "{e}"
    );
}

/// Found by the SVG fuzz target after 13 M executions: stroked text
/// whose outline sends tiny-skia's curvature search (inside usvg's
/// parser) to an `unwrap` on NaN. The panic is this file's error.
#[test]
fn a_panic_inside_the_svg_parser_is_an_error_naming_the_file() {
    let data = include_bytes!("../../tests/data/stroked-text-parser-panic.svg");
    let e = parse_svg(
        data,
        Path::new("panic.svg"),
        &SvgOptions::at_level(4).with_limits(Limits::default()),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("panic.svg") && e.contains("the SVG parser (usvg) failed"),
        "{e}"
    );
}

/// Found by the SVG fuzz target: a stroked circle of radius 8 × 10¹⁸
/// flattened to 2 GB of points before the packer refused its
/// coordinates. Both bounds are now checked while flattening.
#[test]
fn far_away_curves_are_refused_before_they_are_flattened() {
    let parse = |body: &str| {
        let svg = format!(
            r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 100 100">{body}</svg>"#
        );
        parse_svg(
            svg.as_bytes(),
            Path::new("far.svg"),
            &SvgOptions::at_level(4).with_limits(Limits::default()),
        )
        .unwrap_err()
        .to_string()
    };
    let e = parse(
        r#"<circle cx="88" cy="12" r="8111111111111111111.0" fill="none" stroke="black" stroke-width="0.4"/>"#,
    );
    assert!(
        e.contains("far.svg") && e.contains("texture units") && e.contains("beyond ±1e12"),
        "{e}"
    );
    // Within the coordinate bound, but each curve flattens to the most
    // segments one curve may have (65 536).
    let curves = " C 1e9 0 -1e9 100 0 100 C 1e9 100 -1e9 0 0 0".repeat(130);
    let e = parse(&format!(r#"<path d="M0 0{curves}Z"/>"#));
    assert!(
        e.contains("far.svg") && e.contains("flatten to more than 16777216 points"),
        "{e}"
    );
}

/// A fresh folder `tmp/quadtex-io-<name>-<pid>` holding `outside.png` and
/// `dir/sub/` with `in.png`, `deeper/in2.png` and (on Unix) `link.png`, a
/// symbolic link to `outside.png`; returns the folder and `dir/sub`.
fn resource_tree(name: &str) -> (std::path::PathBuf, std::path::PathBuf) {
    let root = std::env::temp_dir().join(format!("quadtex-io-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    let sub = root.join("dir").join("sub");
    std::fs::create_dir_all(sub.join("deeper")).unwrap();
    let png = image::RgbaImage::from_pixel(2, 2, image::Rgba([200, 10, 10, 255]));
    png.save(root.join("outside.png")).unwrap();
    png.save(sub.join("in.png")).unwrap();
    png.save(sub.join("deeper").join("in2.png")).unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink(root.join("outside.png"), sub.join("link.png")).unwrap();
    (root, sub)
}

/// Whether `art` covers the unit square opaquely (the image was drawn).
fn opaque(art: &VectorArt) -> bool {
    let options = VectorOptions {
        max_level: 4,
        ..VectorOptions::default()
    };
    let (tree, _) = QuadTree::from_vector(art, &options).unwrap();
    let f = Fragment::new(0.0, 0.0, 1.0, 1.0).unwrap();
    tree.weighted_colour(&f, 4).0[3] > 0.99
}

/// Loads `sub/a.svg` drawing one image `href` under `policy`.
fn load_with_href(
    sub: &Path,
    href: &str,
    policy: crate::ExternalResources,
) -> Result<VectorArt, Error> {
    let file = sub.join("a.svg");
    std::fs::write(
        &file,
        format!(
            r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 10 10"><image width="10" height="10" href="{href}"/></svg>"#
        ),
    )
    .unwrap();
    let limits = Limits {
        external_resources: policy,
        ..Limits::default()
    };
    load_svg(&file, &SvgOptions::at_level(4).with_limits(limits))
}

#[test]
fn images_outside_the_folder_are_refused_by_default() {
    use crate::ExternalResources::{Anywhere, SameFolder};
    let (root, sub) = resource_tree("svg-resources");
    let absolute = root.join("outside.png").display().to_string();
    let mut refs = vec![
        absolute.as_str(),
        "../../outside.png",
        "deeper/../../../outside.png",
    ];
    if cfg!(unix) {
        refs.push("link.png");
    }
    for href in refs {
        let e = load_with_href(&sub, href, SameFolder).unwrap_err();
        let text = e.to_string();
        assert!(
            matches!(&e, Error::ExternalResource { reference, .. } if reference == href),
            "{href}: {text}"
        );
        assert!(
            text.contains("a.svg") && text.contains(&format!("\"{href}\"")),
            "{text}"
        );
        // Widened, the same file is drawn.
        let art = load_with_href(&sub, href, Anywhere).unwrap();
        assert!(opaque(&art), "{href}");
    }
    // Inside the folder, however written, the default reads it.
    for href in ["in.png", "./in.png", "deeper/in2.png", "deeper/../in.png"] {
        let art = load_with_href(&sub, href, SameFolder).unwrap();
        assert!(opaque(&art), "{href}");
    }
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn resources_none_reads_no_file_but_data_urls() {
    use crate::ExternalResources::None;
    let (root, sub) = resource_tree("svg-resources-none");
    let e = load_with_href(&sub, "in.png", None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("a.svg") && e.contains("\"in.png\" refused") && e.contains("none"),
        "{e}"
    );
    let data = format!("data:image/png;base64,{PNG_2X2}");
    let art = load_with_href(&sub, &data, None).unwrap();
    assert!(opaque(&art));
    std::fs::remove_dir_all(&root).unwrap();
}

/// Many overlapping curved paths (stroked ellipses and filled petals, a
/// small stand-in for the Ghostscript tiger), written to a fresh file.
fn curvy_art(name: &str) -> std::path::PathBuf {
    let mut svg = String::from(r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 200 200">"#);
    for i in 0..24 {
        let t = f64::from(i);
        let (cx, cy) = (
            100.0 + 50.0 * (0.7 * t).cos(),
            100.0 + 50.0 * (0.5 * t).sin(),
        );
        svg += &format!(
            r##"<ellipse cx="{cx:.2}" cy="{cy:.2}" rx="{:.2}" ry="{:.2}" fill="#{:02x}8040" fill-opacity="0.8" stroke="#000" stroke-width="0.4"/>"##,
            20.0 + 2.0 * t,
            10.0 + t,
            (10 * i) % 256
        );
        svg += &format!(
            r##"<path d="M{cx:.2} {cy:.2} C {:.2} {:.2}, {:.2} {:.2}, {:.2} {:.2} S {:.2} {:.2}, {cx:.2} {cy:.2} Z" fill="#2060{:02x}"/>"##,
            cx + 30.0,
            cy - 40.0,
            cx + 60.0,
            cy + 10.0,
            cx + 20.0,
            cy + 30.0,
            cx - 30.0,
            cy + 20.0,
            (7 * i) % 256
        );
    }
    svg += "</svg>";
    let path = std::env::temp_dir().join(format!("quadtex-io-{name}-{}.svg", std::process::id()));
    std::fs::write(&path, svg).unwrap();
    path
}

/// Left to the packer (as `quadtex pack`, Python and C do when no level is
/// given), a level whose estimate is above the memory budget is lowered to
/// the deepest that fits, and the fit says what was asked and what was
/// chosen; a level given is refused with the estimate and the budget.
#[test]
fn default_level_is_lowered_to_fit_the_memory_budget() {
    let path = curvy_art("fit-level");
    let art = load_svg(&path, &SvgOptions::at_level(12)).unwrap();
    let estimates = art.estimate_bytes_per_level(12, None, None);
    // Room for level 10, not for 11.
    let budget = estimates[10];
    assert!(
        estimates[11] > budget && estimates[12] > estimates[11],
        "{estimates:?}"
    );
    let limits = Limits {
        max_memory: budget,
        ..Limits::default()
    };
    let given = SvgOptions::at_level(12).with_limits(limits);
    match pack_svg(&path, &given) {
        Err(
            e @ Error::MemoryBudget {
                estimate,
                budget: b,
                ..
            },
        ) => {
            assert_eq!((estimate, b), (estimates[12], budget));
            let e = e.to_string();
            assert!(
                e.contains("packing at level 12 needs an estimated")
                    && e.contains("lower --max-level"),
                "{e}"
            );
        }
        other => panic!("{:?}", other.map(|(_, r)| r)),
    }
    let left = SvgOptions {
        adjustable: Adjustable {
            max_level: true,
            contour_edges: false,
        },
        ..given
    };
    let (tree, _, fit) = pack_svg_fitted(&path, &left).unwrap();
    assert_eq!(fit.max_level, 10);
    assert_eq!(fit.asked, Some((12, None, estimates[12])));
    assert_eq!((fit.estimate, fit.budget), (Some(budget), Some(budget)));
    assert_eq!(tree.depth(), 10);
    // Nothing fits down to level 8: refused, naming the levels tried.
    let tiny = SvgOptions {
        limits: Limits {
            max_memory: 1024,
            ..Limits::default()
        },
        ..left
    };
    let e = pack_svg(&path, &tiny).unwrap_err().to_string();
    assert!(
        e.contains("packing at level 12 (and at every level down to 8) needs an estimated")
            && e.contains("memory budget of 1.0 KiB (raise --memory-limit)"),
        "{e}"
    );
    let _ = std::fs::remove_file(&path);
}

/// With contour leaves whose edge budget was left to the packer, one that
/// does not fit is raised (fewer, larger leaves hold fewer points) before
/// the level is lowered; the estimate follows what is built.
#[test]
fn default_contour_edges_are_raised_to_fit_the_memory_budget() {
    let path = curvy_art("fit-edges");
    let asked = SvgOptions {
        vector: VectorOptions {
            max_level: 20,
            contour_leaves: Some(16),
            ..VectorOptions::default()
        },
        ..SvgOptions::default()
    };
    let art = load_svg(&path, &asked).unwrap();
    let at = |edges| {
        art.estimate_bytes(&VectorOptions {
            contour_leaves: Some(edges),
            ..asked.vector
        })
    };
    let (sixteen, budget) = (at(16), at(64));
    assert!(sixteen > budget, "{sixteen} vs {budget}");
    let options = SvgOptions {
        limits: Limits {
            max_memory: budget,
            ..Limits::default()
        },
        adjustable: Adjustable {
            max_level: true,
            contour_edges: true,
        },
        ..asked
    };
    let (tree, report, fit) = pack_svg_fitted(&path, &options).unwrap();
    assert_eq!(fit.max_level, 20);
    assert!(
        matches!(fit.contour_leaves, Some(32 | 64)),
        "{:?}",
        fit.contour_leaves
    );
    assert_eq!(fit.asked, Some((20, Some(16), sixteen)));
    assert!(fit.estimate.unwrap() <= budget);
    assert!(report.contour_leaves > 0 && tree.contour_leaves().is_some());
    // The estimate against what was built, at the settings chosen: above
    // it here (it does not see the opaque petals hide what lies under
    // them), never far below.
    let built = tree.node_count() as f64 * 30.0
        + report.contour_leaf_points as f64 * 40.0
        + report.contour_leaves as f64 * 200.0
        + art.point_count() as f64 * 32.0;
    let estimate = fit.estimate.unwrap() as f64;
    assert!(
        (0.8..2.0).contains(&(estimate / built)),
        "estimate {estimate} vs {built} for what was built"
    );
    let _ = std::fs::remove_file(&path);
}
