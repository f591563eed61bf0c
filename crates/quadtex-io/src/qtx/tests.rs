use super::*;
use quadtex_core::BuildOptions;
use quadtex_core::synth;

fn sample() -> QuadTree {
    let g = synth::runway_art().rasterise(64, 64).unwrap();
    QuadTree::from_texels(&g, &BuildOptions::default())
        .unwrap()
        .0
}

/// Recomputes a file's three checksums after an edit (`n` nodes).
fn reseal(b: &mut [u8], n: usize) {
    let crc = crc32fast::hash(&b[..56]);
    b[56..60].copy_from_slice(&crc.to_le_bytes());
    let end = b.len() - 4;
    let bits = n.div_ceil(8);
    let section = &b[64 + bits + 8 * n..end];
    let mut hasher = crc32fast::Hasher::new();
    hasher.update(&b[64..64 + bits]);
    hasher.update(&section[..section_structure_bytes(section, b[31])]);
    let crc = hasher.finalize();
    b[60..64].copy_from_slice(&crc.to_le_bytes());
    let crc = crc32fast::hash(&b[64..end]);
    b[end..].copy_from_slice(&crc.to_le_bytes());
}

fn temp(name: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("quadtex-qtx-{}-{name}", std::process::id()))
}

#[test]
fn round_trips() {
    let t = sample();
    let p = temp("rt.qtx");
    write_qtx(&p, &t, Some((64, 64))).unwrap();
    let (back, info) = read_qtx(&p, &Limits::default()).unwrap();
    assert_eq!(back, t);
    assert_eq!((info.source_width, info.source_height), (64, 64));
    std::fs::remove_file(&p).unwrap();
}

/// A strip keeps its aspect through the file; a header claiming both
/// axes shrunk is refused by name.
#[test]
fn strips_round_trip_with_their_aspect() {
    let g = synth::runway_art().rasterise(64, 8).unwrap();
    let (t, _) = QuadTree::from_texels(&g, &BuildOptions::default()).unwrap();
    assert_eq!(t.aspect().shrink(), Some([0, 3]));
    let mut bytes = Vec::new();
    write_qtx_to(&mut bytes, Path::new("strip"), &t, Some((64, 8))).unwrap();
    let (back, _) = parse_qtx(&bytes, Path::new("strip"), &Limits::default()).unwrap();
    assert_eq!(back, t);
    assert_eq!(back.aspect(), t.aspect());
    bytes[18] = 2;
    let crc = crc32fast::hash(&bytes[..56]);
    bytes[56..60].copy_from_slice(&crc.to_le_bytes());
    let e = parse_qtx(&bytes, Path::new("strip"), &Limits::default()).unwrap_err();
    assert!(e.to_string().contains("aspect"), "{e}");
}

/// A texture of any size keeps its extent through the file (version 4,
/// as its source size) and passes `verify` after reading; strips and
/// squares stay version 2; a version-4 header with shrink bytes or an
/// empty extent is refused by name.
#[test]
fn any_size_round_trips_as_version_4() {
    let bytes: Vec<[u8; 4]> = (0..37u32 * 23)
        .map(|i| {
            let h = (i / 3).wrapping_mul(2_654_435_761);
            [(h >> 8) as u8, (h >> 16) as u8, (h >> 24) as u8, 255]
        })
        .collect();
    let g = quadtex_core::TexelGrid::from_srgb8(37, 23, bytes).unwrap();
    let (t, _) = QuadTree::from_texels(&g, &BuildOptions::default()).unwrap();
    assert_eq!(t.aspect().shrink(), None);
    for source in [Some((37, 23)), None] {
        let mut file = Vec::new();
        write_qtx_to(&mut file, Path::new("odd"), &t, source).unwrap();
        assert_eq!(u32::from_le_bytes(file[8..12].try_into().unwrap()), 4);
        let (back, info) = parse_qtx(&file, Path::new("odd"), &Limits::default()).unwrap();
        assert_eq!(back, t);
        back.verify().unwrap();
        assert_eq!((info.source_width, info.source_height), (37, 23));
    }
    let mut file = Vec::new();
    write_qtx_to(&mut file, Path::new("odd"), &t, Some((37, 23))).unwrap();
    let reheader = |b: &mut Vec<u8>| {
        let crc = crc32fast::hash(&b[..56]);
        b[56..60].copy_from_slice(&crc.to_le_bytes());
    };
    let mut shrunk = file.clone();
    shrunk[19] = 1;
    reheader(&mut shrunk);
    let e = parse_qtx(&shrunk, Path::new("odd"), &Limits::default()).unwrap_err();
    assert!(e.to_string().contains("aspect"), "{e}");
    let mut empty = file.clone();
    empty[20..24].copy_from_slice(&0u32.to_le_bytes());
    reheader(&mut empty);
    let e = parse_qtx(&empty, Path::new("odd"), &Limits::default()).unwrap_err();
    assert!(e.to_string().contains("source_size"), "{e}");
    let mut strip = Vec::new();
    let s = synth::runway_art().rasterise(64, 8).unwrap();
    let (s, _) = QuadTree::from_texels(&s, &BuildOptions::default()).unwrap();
    write_qtx_to(&mut strip, Path::new("strip"), &s, Some((64, 8))).unwrap();
    assert_eq!(u32::from_le_bytes(strip[8..12].try_into().unwrap()), 2);
}

/// A photograph-like 8-bit grid: most of its bottom in texel blocks.
fn photo_sample() -> QuadTree {
    let bytes = (0..32u32 * 32)
        .map(|i| {
            let h = i.wrapping_mul(2_654_435_761);
            [
                (h >> 8) as u8,
                (h >> 16) as u8,
                (h >> 24) as u8,
                255 - (i % 3) as u8,
            ]
        })
        .collect();
    let g = quadtex_core::TexelGrid::from_srgb8(32, 32, bytes).unwrap();
    QuadTree::from_texels(&g, &BuildOptions::default())
        .unwrap()
        .0
}

/// Texel blocks round-trip; their section is checked structurally
/// (checksums skipped, as under fuzzing): counts that lie, flags for
/// the wrong nodes and a block that disowns its node's mean are refused
/// by name.
#[test]
fn texel_blocks_round_trip_and_lies_are_refused() {
    let t = photo_sample();
    let blocks = t.texel_blocks().expect("blocks");
    assert_eq!(blocks.format(), BlockFormat::Srgb8Rgba);
    assert!(blocks.count() > 32, "{}", blocks.count());
    let mut bytes = Vec::new();
    write_qtx_to(&mut bytes, Path::new("photo"), &t, Some((32, 32))).unwrap();
    let (back, _) = parse_qtx(&bytes, Path::new("photo"), &Limits::default()).unwrap();
    assert_eq!(back, t);
    let n = t.node_count() as usize;
    let section = 64 + n.div_ceil(8) + 8 * n;
    let refused = |b: &[u8]| {
        parse_qtx(b, Path::new("photo"), &Limits::default())
            .unwrap_err()
            .to_string()
    };
    // The block count one too high.
    let mut lie = bytes.clone();
    lie[section + 8] += 1;
    reseal(&mut lie, n);
    assert!(refused(&lie).contains("texel_blocks"), "{}", refused(&lie));
    // Flags changed: the blocks no longer match their texels or nodes.
    for flip in [0b1u8, 0b11, 0b1000_0000] {
        let mut lie = bytes.clone();
        lie[section + 16] ^= flip;
        reseal(&mut lie, n);
        let e = refused(&lie);
        assert!(e.contains("texel block"), "{e}");
    }
    // A texel changed: its block no longer averages to its node.
    let mut lie = bytes.clone();
    let first_texel =
        section + 16 + (t.level_stats()[usize::from(blocks.level())].nodes as usize).div_ceil(8);
    lie[first_texel] ^= 0xff;
    reseal(&mut lie, n);
    let e = refused(&lie);
    assert!(e.contains("texel block averages"), "{e}");
    // An unknown block format.
    let mut lie = bytes.clone();
    lie[28] = 9;
    reseal(&mut lie, n);
    assert!(refused(&lie).contains("block_format"), "{}", refused(&lie));
}

/// A mapped file gives the tree a full read gives, and the same answers;
/// a corrupt colour is refused on mapping by the payload checksum, while
/// mapped unverified it opens (and queries without panicking) but fails
/// `verify`; corrupt structure is refused on opening either way.
#[test]
fn mapped_files_open_lazily_and_verify_on_demand() {
    let p = temp("map.qtx");
    for (tree, name) in [(sample(), "vector"), (photo_sample(), "photo")] {
        write_qtx(&p, &tree, None).unwrap();
        let (mapped, info) = map_qtx(&p, &Limits::default()).unwrap();
        assert_eq!(mapped, tree, "{name}");
        assert_eq!(info.file_bytes, std::fs::metadata(&p).unwrap().len());
        mapped.verify().unwrap();
        let f = quadtex_core::Fragment::new(0.1, 0.23, 0.61, 0.9).unwrap();
        assert_eq!(
            mapped.weighted_colour(&f, 30),
            tree.weighted_colour(&f, 30),
            "{name}"
        );
        let good = std::fs::read(&p).unwrap();
        let n = tree.node_count() as usize;
        let colours = 64 + n.div_ceil(8);
        // The last node's alpha zeroed: no longer premultiplied, and no
        // longer its parent's share.
        let mut bytes = good.clone();
        bytes[colours + 8 * n - 2..colours + 8 * n].fill(0);
        std::fs::write(&p, &bytes).unwrap();
        let e = map_qtx(&p, &Limits::default()).unwrap_err().to_string();
        assert!(e.contains("payload_crc") && e.contains("colours"), "{e}");
        let (lazy, _) = map_qtx_unverified(&p, &Limits::default()).unwrap();
        let w = lazy.weighted_colour(&f, 30);
        assert!(w.0.iter().all(|c| c.is_finite()));
        let e = lazy.verify().unwrap_err().to_string();
        assert!(e.contains("node"), "{e}");
        let e = read_qtx(&p, &Limits::default()).unwrap_err().to_string();
        assert!(e.contains("payload_crc"), "{e}");
        // An inner flag flipped: refused on opening, by its checksum.
        let mut bytes = good.clone();
        bytes[64] ^= 1;
        std::fs::write(&p, &bytes).unwrap();
        for open in [map_qtx, map_qtx_unverified] {
            let e = open(&p, &Limits::default()).unwrap_err().to_string();
            assert!(e.contains("structure_crc"), "{e}");
        }
        // Resealed, the same flip is refused by the structure checks.
        reseal(&mut bytes, n);
        std::fs::write(&p, &bytes).unwrap();
        for open in [map_qtx, map_qtx_unverified] {
            let e = open(&p, &Limits::default()).unwrap_err().to_string();
            assert!(e.contains("nodes") || e.contains("inner_bits"), "{e}");
        }
    }
    std::fs::remove_file(&p).unwrap();
}

/// Bits flipped at random in the colours or texels of a packed file (50
/// copies, one to three bits each, over a vector tree and a photo with
/// texel blocks): every opener that promises
/// detection refuses every copy, naming the file and the payload checksum.
#[test]
fn flipped_payload_bits_are_refused_by_every_verified_opener() {
    let p = temp("flips.qtx");
    let mut rng = 0x9E37_79B9_7F4A_7C15_u64;
    let mut next = move |below: usize| {
        // xorshift64*: a fixed sequence, so a failure repeats.
        rng ^= rng >> 12;
        rng ^= rng << 25;
        rng ^= rng >> 27;
        (rng.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as usize % below
    };
    for (tree, name) in [(sample(), "vector"), (photo_sample(), "photo")] {
        write_qtx(&p, &tree, None).unwrap();
        let good = std::fs::read(&p).unwrap();
        let n = tree.node_count() as usize;
        let colours = 64 + n.div_ceil(8);
        // The bytes no structure checksum covers: the colours, and the
        // texels after a block section's counts and flags.
        let end = good.len() - 4;
        let texels = colours + 8 * n + structure_bytes(&good[colours + 8 * n..end]);
        let texels = if tree.texel_blocks().is_some() {
            texels..end
        } else {
            end..end
        };
        let unchecked = 8 * n + texels.len();
        for copy in 0..50 {
            let mut bytes = good.clone();
            let flips = 1 + copy % 3;
            let mut seen = Vec::new();
            while seen.len() < flips {
                let k = next(8 * unchecked);
                if seen.contains(&k) {
                    continue;
                }
                seen.push(k);
                let byte = k / 8;
                let at = if byte < 8 * n {
                    colours + byte
                } else {
                    texels.start + byte - 8 * n
                };
                bytes[at] ^= 1 << (k % 8);
            }
            std::fs::write(&p, &bytes).unwrap();
            let shown = p.display().to_string();
            let results = [
                ("read_qtx", read_qtx(&p, &Limits::default()).map(|_| ())),
                ("map_qtx", map_qtx(&p, &Limits::default()).map(|_| ())),
                (
                    "parse_qtx",
                    parse_qtx(&bytes, &p, &Limits::default()).map(|_| ()),
                ),
            ];
            for (opener, r) in results {
                let e = r.expect_err(&format!("{name} copy {copy}: {opener} accepted {seen:?}"));
                let e = e.to_string();
                assert!(
                    e.contains(&shown) && e.contains("payload_crc") && e.contains("bytes"),
                    "{name} copy {copy} {opener}: {e}"
                );
            }
        }
    }
    std::fs::remove_file(&p).unwrap();
}

/// Version-1 files (no structure checksum) still read, mapped or not;
/// mapping one checks its payload checksum instead.
/// A tree with gradient leaves round-trips (read and mapped) as a
/// version-3 file; a leaf on an inner node, a paint index out of range
/// and a truncated section are refused by field.
#[test]
fn gradient_leaves_round_trip_and_lies_are_refused() {
    use quadtex_core::{FillRule, Paint, VectorArt, VectorOptions};
    use quadtex_core::{Gradient, Interpolation, Spread, Stop};
    let ramp = Gradient::linear(
        [1.0, 0.0, 0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0],
        [0.3, 0.1],
        vec![
            Stop {
                offset: 0.0,
                colour: [0.1, 0.5, 0.9],
                opacity: 1.0,
            },
            Stop {
                offset: 1.0,
                colour: [0.9, 0.4, 0.0],
                opacity: 0.5,
            },
        ],
        Spread::Repeat,
        Interpolation::Srgb,
    )
    .unwrap();
    let mut art = VectorArt::new();
    art.fill_paint(
        vec![vec![[0.1, 0.2], [0.8, 0.1], [0.7, 0.9]]],
        FillRule::NonZero,
        Paint::Gradient(ramp),
        &[],
        None,
    )
    .unwrap();
    let options = VectorOptions {
        max_level: 9,
        ..VectorOptions::default()
    };
    let (t, _) = QuadTree::from_vector(&art, &options).unwrap();
    let leaves = t.gradient_leaves().expect("gradient leaves");
    assert_eq!(t.depth(), 9);
    let path = temp("gradient.qtx");
    write_qtx(&path, &t, None).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(u32::from_le_bytes(bytes[8..12].try_into().unwrap()), 3);
    assert_eq!(bytes[31], LEAF_KIND_GRADIENT);
    let limits = Limits::default();
    let (back, _) = read_qtx(&path, &limits).unwrap();
    assert_eq!(back, t);
    let (mapped, _) = map_qtx(&path, &limits).unwrap();
    assert_eq!(mapped, t);
    let f = quadtex_core::Fragment::new(0.4, 0.4, 0.4 + 1e-7, 0.4 + 1e-7).unwrap();
    assert_eq!(mapped.weighted_colour(&f, 30), t.weighted_colour(&f, 30));
    // The section: length, header, paints, then (node, paint) pairs.
    let n = t.node_count() as usize;
    let section = HEADER_BYTES + n.div_ceil(8) + 8 * n;
    let pairs = bytes.len() - 4 - 8 * leaves.count();
    let refused = |b: &[u8]| parse_qtx(b, &path, &limits).unwrap_err().to_string();
    let mut lie = bytes.clone();
    lie[pairs..pairs + 4].copy_from_slice(&0u32.to_le_bytes());
    reseal(&mut lie, n);
    let e = refused(&lie);
    assert!(e.contains("gradient leaves") && e.contains("inner"), "{e}");
    let mut lie = bytes.clone();
    lie[pairs + 4..pairs + 8].copy_from_slice(&7u32.to_le_bytes());
    reseal(&mut lie, n);
    assert!(refused(&lie).contains("paint 7"), "{}", refused(&lie));
    let mut lie = bytes.clone();
    lie[section..section + 8].copy_from_slice(&5u64.to_le_bytes());
    reseal(&mut lie, n);
    assert!(
        refused(&lie).contains("gradient_leaves"),
        "{}",
        refused(&lie)
    );
    let mut lie = bytes.clone();
    lie[31] = 4;
    reseal(&mut lie, n);
    assert!(refused(&lie).contains("leaf_kinds"), "{}", refused(&lie));
    // Declared as contour leaves, the gradient section does not parse.
    let mut lie = bytes.clone();
    lie[31] = LEAF_KIND_CONTOUR;
    reseal(&mut lie, n);
    assert!(
        refused(&lie).contains("contour_leaves"),
        "{}",
        refused(&lie)
    );
    // A version-2 reader's view: version 2 with the flag is refused.
    let mut lie = bytes.clone();
    lie[8..12].copy_from_slice(&2u32.to_le_bytes());
    reseal(&mut lie, n);
    assert!(refused(&lie).contains("leaf_kinds"), "{}", refused(&lie));
    std::fs::remove_file(&path).ok();
}

/// A tree with contour leaves (and gradient leaves) round-trips, read
/// and mapped; a point moved out of its leaf's square, a count that
/// lies and an unknown fill rule are refused by field.
#[test]
fn contour_leaves_round_trip_and_lies_are_refused() {
    use quadtex_core::{FillRule, Rgba, VectorArt, VectorOptions};
    let mut art = VectorArt::new();
    art.fill(
        vec![vec![[0.1, 0.15], [0.85, 0.3], [0.4, 0.9]]],
        FillRule::NonZero,
        Rgba::new(0.2, 0.4, 0.1, 0.6),
        &[],
    )
    .unwrap();
    art.fill(
        vec![vec![[0.3, 0.3], [0.6, 0.3], [0.6, 0.6], [0.3, 0.6]]],
        FillRule::EvenOdd,
        Rgba::new(0.5, 0.0, 0.0, 0.5),
        &[],
    )
    .unwrap();
    art.set_curve_tolerance(quadtex_core::CONTOUR_CURVE_TOLERANCE);
    let options = VectorOptions {
        max_level: 8,
        contour_leaves: Some(8),
        ..VectorOptions::default()
    };
    let (t, _) = QuadTree::from_vector(&art, &options).unwrap();
    let leaves = t.contour_leaves().expect("contour leaves");
    assert_eq!(
        leaves.curve_tolerance(),
        Some(quadtex_core::CONTOUR_CURVE_TOLERANCE)
    );
    assert_eq!(t.depth(), 30);
    let path = temp("contour.qtx");
    write_qtx(&path, &t, None).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(bytes[31], LEAF_KIND_CONTOUR);
    let limits = Limits::default();
    let (back, _) = read_qtx(&path, &limits).unwrap();
    assert_eq!(back, t);
    let (mapped, _) = map_qtx(&path, &limits).unwrap();
    assert_eq!(mapped, t);
    let f = quadtex_core::Fragment::new(0.5, 0.5, 0.5 + 1e-9, 0.5 + 2e-9).unwrap();
    assert_eq!(mapped.weighted_colour(&f, 30), t.weighted_colour(&f, 30));
    let n = t.node_count() as usize;
    let refused = |b: &[u8]| parse_qtx(b, &path, &limits).unwrap_err().to_string();
    let end = bytes.len() - 4;
    let mut lie = bytes.clone();
    lie[end - 16..end - 8].copy_from_slice(&2.0f64.to_le_bytes());
    reseal(&mut lie, n);
    let e = refused(&lie);
    assert!(e.contains("outside its square"), "{e}");
    let section = HEADER_BYTES + n.div_ceil(8) + 8 * n;
    // A stated curve tolerance that is no distance.
    for bad in [-1.0f32, f32::NAN, 2.0] {
        let mut lie = bytes.clone();
        lie[section + 9..section + 13].copy_from_slice(&bad.to_le_bytes());
        reseal(&mut lie, n);
        let e = refused(&lie);
        assert!(e.contains("curve tolerance"), "{e}");
    }
    let mut lie = bytes.clone();
    // The point count (the fifth count after length, depth and reserved).
    let at = section + 8 + 8 + 32;
    let points = u64::from_le_bytes(lie[at..at + 8].try_into().unwrap());
    lie[at..at + 8].copy_from_slice(&(points + 1).to_le_bytes());
    reseal(&mut lie, n);
    assert!(
        refused(&lie).contains("contour_leaves"),
        "{}",
        refused(&lie)
    );
    let mut lie = bytes.clone();
    // No groups in this art: the pieces follow the leaves.
    let first_piece = section + 8 + 8 + 40 + 16 * leaves.count();
    lie[first_piece + 32] = 9;
    reseal(&mut lie, n);
    assert!(refused(&lie).contains("fill rule 9"), "{}", refused(&lie));
    std::fs::remove_file(&path).ok();
}

#[test]
fn version_1_files_still_read() {
    let t = photo_sample();
    let mut bytes = Vec::new();
    write_qtx_to(&mut bytes, Path::new("v1"), &t, None).unwrap();
    bytes[8..12].copy_from_slice(&1u32.to_le_bytes());
    bytes[60..64].fill(0);
    let crc = crc32fast::hash(&bytes[..56]);
    bytes[56..60].copy_from_slice(&crc.to_le_bytes());
    let (back, _) = parse_qtx(&bytes, Path::new("v1"), &Limits::default()).unwrap();
    assert_eq!(back, t);
    let (lazy, _) =
        parse_qtx_structure(bytes.clone().into(), Path::new("v1"), &Limits::default()).unwrap();
    assert_eq!(lazy, t);
    let last = bytes.len() - 5;
    bytes[last] ^= 1;
    let e = parse_qtx_structure(bytes.into(), Path::new("v1"), &Limits::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("payload_crc"), "{e}");
}

#[test]
fn every_single_byte_flip_and_truncation_is_an_error() {
    let p = temp("flip.qtx");
    let q = temp("flip-bad.qtx");
    for tree in [sample(), photo_sample()] {
        write_qtx(&p, &tree, None).unwrap();
        let good = std::fs::read(&p).unwrap();
        for i in (0..good.len()).step_by(7) {
            let mut bytes = good.clone();
            bytes[i] ^= 0x10;
            std::fs::write(&q, &bytes).unwrap();
            assert!(
                read_qtx(&q, &Limits::default()).is_err(),
                "flip at byte {i} accepted"
            );
        }
        for len in [0, 10, 63, 64, good.len() / 2, good.len() - 1] {
            std::fs::write(&q, &good[..len]).unwrap();
            let e = read_qtx(&q, &Limits::default()).unwrap_err().to_string();
            assert!(e.contains("flip-bad.qtx"), "{e}");
        }
    }
    std::fs::remove_file(&p).unwrap();
    std::fs::remove_file(&q).unwrap();
}

#[test]
fn absurd_sizes_are_refused_before_allocating() {
    let p = temp("huge.qtx");
    write_qtx(&p, &sample(), None).unwrap();
    let mut bytes = std::fs::read(&p).unwrap();
    // Claim 2^40 nodes with a valid header checksum.
    bytes[32..40].copy_from_slice(&(1u64 << 40).to_le_bytes());
    let crc = crc32fast::hash(&bytes[..56]);
    bytes[56..60].copy_from_slice(&crc.to_le_bytes());
    std::fs::write(&p, &bytes).unwrap();
    let e = read_qtx(&p, &Limits::default()).unwrap_err();
    assert!(
        matches!(
            e,
            Error::Limit {
                limit: "max_nodes",
                ..
            }
        ),
        "{e}"
    );
    std::fs::remove_file(&p).unwrap();
}
