//! MSH 4.1 files written here, as text and as binary bytes per the format's
//! specification (size_t of 8 bytes, little-endian), so the tests need no Gmsh.

use super::*;

/// A node block: entity dimension, entity tag, nodes by tag.
type NodeBlock = (i32, i32, Vec<(u64, [f64; 3])>);
/// An element block: entity dimension, entity tag, Gmsh type, elements (tag,
/// node tags).
type ElementBlock = (i32, i32, i32, Vec<(u64, Vec<u64>)>);

/// The parts of a small MSH 4.1 file, written as ASCII or binary.
#[derive(Clone, Default)]
struct Fixture {
    /// `$PhysicalNames`: dimension, tag, name.
    names: Vec<(usize, i32, &'static str)>,
    /// Entities (dimension 1, 2, 3): tag and physical tags.
    entities: [Vec<(i32, Vec<i32>)>; 3],
    node_blocks: Vec<NodeBlock>,
    element_blocks: Vec<ElementBlock>,
}

impl Fixture {
    fn node_range(&self) -> (usize, u64, u64) {
        let tags: Vec<u64> = self
            .node_blocks
            .iter()
            .flat_map(|b| b.2.iter().map(|n| n.0))
            .collect();
        let min = tags.iter().copied().min().unwrap_or(0);
        let max = tags.iter().copied().max().unwrap_or(0);
        (tags.len(), min, max)
    }

    fn element_range(&self) -> (usize, u64, u64) {
        let tags: Vec<u64> = self
            .element_blocks
            .iter()
            .flat_map(|b| b.3.iter().map(|e| e.0))
            .collect();
        let min = tags.iter().copied().min().unwrap_or(0);
        let max = tags.iter().copied().max().unwrap_or(0);
        (tags.len(), min, max)
    }

    fn names_section(&self) -> String {
        if self.names.is_empty() {
            return String::new();
        }
        let mut s = format!("$PhysicalNames\n{}\n", self.names.len());
        for (d, t, n) in &self.names {
            s += &format!("{d} {t} \"{n}\"\n");
        }
        s + "$EndPhysicalNames\n"
    }

    fn ascii(&self) -> String {
        let mut s = String::from("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n");
        s += &self.names_section();
        s += "$Entities\n0";
        for e in &self.entities {
            s += &format!(" {}", e.len());
        }
        s += "\n";
        for e in &self.entities {
            for (tag, phys) in e {
                s += &format!("{tag} 0 0 0 1 1 1 {}", phys.len());
                for p in phys {
                    s += &format!(" {p}");
                }
                s += " 0\n";
            }
        }
        s += "$EndEntities\n$Nodes\n";
        let (n, min, max) = self.node_range();
        s += &format!("{} {n} {min} {max}\n", self.node_blocks.len());
        for (d, t, nodes) in &self.node_blocks {
            s += &format!("{d} {t} 0 {}\n", nodes.len());
            for (tag, _) in nodes {
                s += &format!("{tag}\n");
            }
            for (_, x) in nodes {
                s += &format!("{} {} {}\n", x[0], x[1], x[2]);
            }
        }
        s += "$EndNodes\n$Elements\n";
        let (n, min, max) = self.element_range();
        s += &format!("{} {n} {min} {max}\n", self.element_blocks.len());
        for (d, t, ty, elements) in &self.element_blocks {
            s += &format!("{d} {t} {ty} {}\n", elements.len());
            for (tag, nodes) in elements {
                s += &tag.to_string();
                for n in nodes {
                    s += &format!(" {n}");
                }
                s += "\n";
            }
        }
        s + "$EndElements\n"
    }

    /// The same file in binary: numbers as little-endian bytes (int 4, size_t
    /// 8, double 8), `$PhysicalNames` as text.
    fn binary(&self) -> Vec<u8> {
        let mut b = b"$MeshFormat\n4.1 1 8\n".to_vec();
        b.extend(1i32.to_le_bytes());
        b.extend(b"\n$EndMeshFormat\n");
        b.extend(self.names_section().bytes());
        b.extend(b"$Entities\n");
        b.extend(0u64.to_le_bytes());
        for e in &self.entities {
            b.extend((e.len() as u64).to_le_bytes());
        }
        for e in &self.entities {
            for (tag, phys) in e {
                b.extend(tag.to_le_bytes());
                for x in [0.0f64, 0.0, 0.0, 1.0, 1.0, 1.0] {
                    b.extend(x.to_le_bytes());
                }
                b.extend((phys.len() as u64).to_le_bytes());
                for p in phys {
                    b.extend(p.to_le_bytes());
                }
                b.extend(0u64.to_le_bytes());
            }
        }
        b.extend(b"\n$EndEntities\n$Nodes\n");
        let (n, min, max) = self.node_range();
        for v in [self.node_blocks.len() as u64, n as u64, min, max] {
            b.extend(v.to_le_bytes());
        }
        for (d, t, nodes) in &self.node_blocks {
            for v in [*d, *t, 0] {
                b.extend(v.to_le_bytes());
            }
            b.extend((nodes.len() as u64).to_le_bytes());
            for (tag, _) in nodes {
                b.extend(tag.to_le_bytes());
            }
            for (_, x) in nodes {
                for c in x {
                    b.extend(c.to_le_bytes());
                }
            }
        }
        b.extend(b"\n$EndNodes\n$Elements\n");
        let (n, min, max) = self.element_range();
        for v in [self.element_blocks.len() as u64, n as u64, min, max] {
            b.extend(v.to_le_bytes());
        }
        for (d, t, ty, elements) in &self.element_blocks {
            for v in [*d, *t, *ty] {
                b.extend(v.to_le_bytes());
            }
            b.extend((elements.len() as u64).to_le_bytes());
            for (tag, nodes) in elements {
                b.extend(tag.to_le_bytes());
                for n in nodes {
                    b.extend(n.to_le_bytes());
                }
            }
        }
        b.extend(b"\n$EndElements\n");
        b
    }
}

fn opts(dim: usize) -> ImportOptions<'static> {
    ImportOptions {
        dim,
        unit: 1.0,
        region: None,
        allow_disconnected: false,
    }
}

fn close(a: &[[f64; 3]], b: &[[f64; 3]]) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(p, q)| p.iter().zip(q).all(|(x, y)| (x - y).abs() <= 1e-15))
}

/// Two triangles on the square [0, 10] mm, as Gmsh would write it: sparse node
/// tags, a stray node 50, lines for `bottom` and `top` (the latter written
/// against the outward direction).
const TRI_SQUARE: &str = "$MeshFormat
4.1 0 8
$EndMeshFormat
$PhysicalNames
3
1 1 \"bottom\"
1 2 \"top\"
2 3 \"plate\"
$EndPhysicalNames
$Entities
0 2 1 0
1 0 0 0 10 0 0 1 1 0
2 0 10 0 10 10 0 1 2 0
1 0 0 0 10 10 0 1 3 2 1 2
$EndEntities
$Nodes
1 5 10 50
2 1 0 5
10
20
30
40
50
0 0 0
10 0 0
10 10 0
0 10 0
50 50 0
$EndNodes
$Elements
3 4 1 4
1 1 1 1
1 10 20
1 2 1 1
2 40 30
2 1 2 2
3 10 20 30
4 10 30 40
$EndElements
";

#[test]
fn two_triangle_square_compacts_scales_and_names_faces() {
    let o = ImportOptions {
        unit: 1e-3,
        ..opts(2)
    };
    let m = parse_msh(TRI_SQUARE.as_bytes(), &o).unwrap();
    assert_eq!(m.dim, 2);
    assert_eq!(m.kind, CellKind::Tri3);
    let want = [
        [0.0, 0.0, 0.0],
        [0.01, 0.0, 0.0],
        [0.01, 0.01, 0.0],
        [0.0, 0.01, 0.0],
    ];
    assert!(close(&m.nodes, &want), "{:?}", m.nodes);
    assert_eq!(m.unused_nodes, 1);
    assert_eq!(m.cells, vec![vec![0, 1, 2], vec![0, 2, 3]]);
    assert_eq!(m.cell_tags, vec![3, 4]);
    assert_eq!(
        m.boundary,
        vec![vec![0, 1], vec![1, 2], vec![2, 3], vec![3, 0]]
    );
    let faces: Vec<(&str, &Vec<Vec<usize>>)> = m
        .faces
        .iter()
        .map(|f| (f.name.as_str(), &f.facets))
        .collect();
    // `top` was written 40 30 and comes back outward, 30 40.
    assert_eq!(
        faces,
        vec![("bottom", &vec![vec![0, 1]]), ("top", &vec![vec![2, 3]])]
    );
    assert_eq!(m.pieces, 1);
    let again = parse_msh(
        TRI_SQUARE.as_bytes(),
        &ImportOptions {
            region: Some("plate"),
            ..o
        },
    )
    .unwrap();
    assert_eq!(again, m);
}

/// 3 x 3 nodes on [0, 2]^2 (tags 1..9, row by row, in two node blocks),
/// quadrilaterals 1-2 in the left column (surface 1, `left_half`), 3-4 in the
/// right one (surface 2, `right_half`); lines `left`, `right` and, with
/// `middle`, the line x = 1 between the halves.
fn quad_grid(middle: bool) -> Fixture {
    let node = |t: u64| (t, [((t - 1) % 3) as f64, ((t - 1) / 3) as f64, 0.0]);
    let mut f = Fixture {
        names: vec![
            (1, 1, "left"),
            (1, 3, "right"),
            (2, 4, "left_half"),
            (2, 5, "right_half"),
            (2, 6, "empty"),
        ],
        entities: [
            vec![(1, vec![1]), (3, vec![3])],
            vec![(1, vec![4]), (2, vec![5])],
            vec![],
        ],
        node_blocks: vec![
            (2, 1, (1..=5).map(node).collect()),
            (2, 2, (6..=9).map(node).collect()),
        ],
        element_blocks: vec![
            (1, 1, 1, vec![(5, vec![4, 1]), (6, vec![7, 4])]),
            (1, 3, 1, vec![(9, vec![3, 6]), (10, vec![6, 9])]),
            (2, 1, 3, vec![(1, vec![1, 2, 5, 4]), (2, vec![4, 5, 8, 7])]),
            (2, 2, 3, vec![(3, vec![2, 3, 6, 5]), (4, vec![5, 6, 9, 8])]),
        ],
    };
    if middle {
        f.names.push((1, 2, "middle"));
        f.entities[0].push((2, vec![2]));
        f.element_blocks
            .push((1, 2, 1, vec![(7, vec![2, 5]), (8, vec![5, 8])]));
    }
    f
}

#[test]
fn quad_grid_2x2_whole_body() {
    let m = parse_msh(quad_grid(false).ascii().as_bytes(), &opts(2)).unwrap();
    assert_eq!(m.kind, CellKind::Quad4);
    assert_eq!(m.nodes.len(), 9);
    assert_eq!(m.nodes[5], [2.0, 1.0, 0.0]);
    assert_eq!(m.cells.len(), 4);
    assert_eq!(m.cells[0], vec![0, 1, 4, 3]);
    assert_eq!(m.cell_tags, vec![1, 2, 3, 4]);
    assert_eq!(m.boundary.len(), 8);
    assert_eq!(m.unused_nodes, 0);
    let left = &m.faces[0];
    assert_eq!(left.name, "left");
    // Outward on x = 0 runs downward: 3 -> 0 and 6 -> 3.
    assert_eq!(left.facets, vec![vec![3, 0], vec![6, 3]]);
    assert_eq!(m.faces[1].name, "right");
    assert_eq!(m.faces[1].facets, vec![vec![2, 5], vec![5, 8]]);
}

#[test]
fn region_takes_its_cells_and_the_faces_on_them() {
    let text = quad_grid(true).ascii();
    let o = ImportOptions {
        region: Some("left_half"),
        ..opts(2)
    };
    let m = parse_msh(text.as_bytes(), &o).unwrap();
    assert_eq!(m.cells.len(), 2);
    // Nodes 1, 2, 4, 5, 7, 8 of the file; 3, 6, 9 belong to the other half
    // (used, so not counted as unused).
    assert_eq!(m.nodes.len(), 6);
    assert_eq!(m.unused_nodes, 0);
    assert_eq!(m.cells, vec![vec![0, 1, 3, 2], vec![2, 3, 5, 4]]);
    let names: Vec<&str> = m.faces.iter().map(|f| f.name.as_str()).collect();
    assert_eq!(names, ["left", "middle"]);
    assert_eq!(m.faces[1].facets, vec![vec![1, 3], vec![3, 5]]);
    // The whole mesh: `middle` runs through the body.
    let e = parse_msh(text.as_bytes(), &opts(2)).unwrap_err();
    assert_eq!(
        e,
        MeshError::FaceNotOnBoundary {
            name: "middle".into(),
            off: 2,
            total: 2
        }
    );
    assert!(e.to_string().contains("`middle`"), "{e}");
}

#[test]
fn unknown_region_lists_the_names_nearest_first() {
    let text = quad_grid(false).ascii();
    let e = parse_msh(
        text.as_bytes(),
        &ImportOptions {
            region: Some("rigth_half"),
            ..opts(2)
        },
    )
    .unwrap_err();
    let MeshError::RegionNotFound { nearest, .. } = &e else {
        panic!("{e:?}")
    };
    assert_eq!(nearest, &["right_half", "left_half", "empty"]);
    assert!(e.to_string().contains("`right_half`, `left_half`"), "{e}");
    // A face group's name is not a region.
    let e = parse_msh(
        text.as_bytes(),
        &ImportOptions {
            region: Some("left"),
            ..opts(2)
        },
    )
    .unwrap_err();
    assert!(
        matches!(&e, MeshError::RegionNotFound { other_dims, .. } if other_dims == &[1]),
        "{e:?}"
    );
    assert!(e.to_string().contains("is of dimension 1"), "{e}");
}

#[test]
fn a_region_without_elements_is_an_error() {
    let e = parse_msh(
        quad_grid(false).ascii().as_bytes(),
        &ImportOptions {
            region: Some("empty"),
            ..opts(2)
        },
    )
    .unwrap_err();
    assert_eq!(
        e,
        MeshError::EmptyRegion {
            name: "empty".into()
        }
    );
}

/// The unit tetrahedron (mm), its face z = 0 as the group `base`.
fn tet(nodes: [u64; 4]) -> Fixture {
    Fixture {
        names: vec![(2, 1, "base"), (3, 2, "solid")],
        entities: [vec![], vec![(1, vec![1])], vec![(1, vec![2])]],
        node_blocks: vec![(
            3,
            1,
            vec![
                (1, [0.0, 0.0, 0.0]),
                (2, [1.0, 0.0, 0.0]),
                (3, [0.0, 1.0, 0.0]),
                (4, [0.0, 0.0, 1.0]),
            ],
        )],
        element_blocks: vec![
            (2, 1, 2, vec![(1, vec![1, 2, 3])]),
            (3, 1, 4, vec![(2, nodes.to_vec())]),
        ],
    }
}

#[test]
fn single_tetrahedron() {
    let m = parse_msh(tet([1, 2, 3, 4]).ascii().as_bytes(), &opts(3)).unwrap();
    assert_eq!(m.kind, CellKind::Tet4);
    assert_eq!(m.cells, vec![vec![0, 1, 2, 3]]);
    assert_eq!(m.cell_tags, vec![2]);
    // The four faces in `fem::Element::Tet4`'s order, each outward.
    assert_eq!(
        m.boundary,
        vec![vec![0, 2, 1], vec![0, 1, 3], vec![1, 2, 3], vec![0, 3, 2]]
    );
    assert_eq!(m.faces.len(), 1);
    assert_eq!(m.faces[0].name, "base");
    assert_eq!(m.faces[0].facets, vec![vec![0, 2, 1]]);
}

#[test]
fn inverted_tetrahedron_is_reported_with_id_and_centroid() {
    let e = parse_msh(tet([1, 3, 2, 4]).ascii().as_bytes(), &opts(3)).unwrap_err();
    assert_eq!(
        e,
        MeshError::Inverted {
            element: 2,
            centroid: [0.25, 0.25, 0.25]
        }
    );
    assert!(e.to_string().contains("element 2"), "{e}");
}

/// The unit cube (tags 1..8 as VTK), its top as the group `top`; `squash`
/// moves the top to z = 0 (a degenerate cell).
fn hex(squash: bool) -> Fixture {
    let z = if squash { 0.0 } else { 1.0 };
    let corners = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, z],
        [1.0, 0.0, z],
        [1.0, 1.0, z],
        [0.0, 1.0, z],
    ];
    Fixture {
        names: vec![(2, 1, "top")],
        entities: [vec![], vec![(6, vec![1])], vec![(1, vec![])]],
        node_blocks: vec![(3, 1, (1..=8).zip(corners).collect())],
        element_blocks: vec![
            (2, 6, 3, vec![(2, vec![5, 6, 7, 8])]),
            (3, 1, 5, vec![(1, (1..=8).collect())]),
        ],
    }
}

#[test]
fn single_hexahedron_and_a_flat_one() {
    let m = parse_msh(hex(false).ascii().as_bytes(), &opts(3)).unwrap();
    assert_eq!(m.kind, CellKind::Hex8);
    assert_eq!(m.boundary.len(), 6);
    assert_eq!(m.faces[0].facets, vec![vec![4, 5, 6, 7]]);
    let e = parse_msh(hex(true).ascii().as_bytes(), &opts(3)).unwrap_err();
    assert!(matches!(e, MeshError::Inverted { element: 1, .. }), "{e:?}");
}

#[test]
fn binary_reads_as_ascii() {
    for (f, dim) in [
        (quad_grid(true), 2),
        (tet([1, 2, 3, 4]), 3),
        (hex(false), 3),
    ] {
        let o = ImportOptions {
            region: (dim == 2).then_some("left_half"),
            ..opts(dim)
        };
        let ascii = parse_msh(f.ascii().as_bytes(), &o).unwrap();
        let binary = parse_msh(&f.binary(), &o).unwrap();
        assert_eq!(ascii, binary);
    }
}

#[test]
fn a_file_from_disk_and_a_missing_one() {
    let dir = std::env::temp_dir().join(format!("cso-msh-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("square.msh");
    std::fs::write(&path, TRI_SQUARE).unwrap();
    assert_eq!(read_msh(&path, &opts(2)).unwrap().cells.len(), 2);
    let missing = dir.join("nope.msh");
    let e = read_msh(&missing, &opts(2)).unwrap_err();
    assert!(matches!(e, MeshError::Unreadable { .. }), "{e:?}");
    assert!(e.to_string().contains("nope.msh"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn other_versions_and_other_files() {
    let e = parse_msh(b"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n", &opts(2)).unwrap_err();
    assert_eq!(
        e,
        MeshError::Version {
            found: "2.2".into()
        }
    );
    let m = e.to_string();
    assert!(
        m.contains("MSH 2.2") && m.contains("gmsh -format msh41"),
        "{m}"
    );
    assert!(m.contains("Mesh.MshFileVersion = 4.1"), "{m}");
    let e = parse_msh(b"solid cube\nendsolid\n", &opts(2)).unwrap_err();
    assert_eq!(e, MeshError::NotMsh);
    let e = parse_msh(b"$MeshFormat\n4.1 0 99999999999999999999\n", &opts(2)).unwrap_err();
    assert!(matches!(e, MeshError::Parse(_)), "{e:?}");
}

#[test]
fn a_truncated_file_is_a_parse_error() {
    let cut = TRI_SQUARE.find("10 10 0").unwrap();
    let e = parse_msh(&TRI_SQUARE.as_bytes()[..cut], &opts(2)).unwrap_err();
    let MeshError::Parse(m) = &e else {
        panic!("{e:?}")
    };
    assert!(m.lines().count() < 40, "{m}");
}

#[test]
fn no_elements_of_the_scene_dimension() {
    let e = parse_msh(TRI_SQUARE.as_bytes(), &opts(3)).unwrap_err();
    assert_eq!(
        e,
        MeshError::NoElements {
            dim: 3,
            found: vec![(1, 2), (2, 2)]
        }
    );
    assert!(e.to_string().contains("no 3D elements"), "{e}");
}

/// A triangle and a quadrilateral sharing the edge x = 1.
fn mixed(quad_type: i32, quad_nodes: Vec<u64>) -> Fixture {
    Fixture {
        entities: [vec![], vec![(1, vec![])], vec![]],
        node_blocks: vec![(
            2,
            1,
            vec![
                (1, [0.0, 0.0, 0.0]),
                (2, [1.0, 0.0, 0.0]),
                (3, [1.0, 1.0, 0.0]),
                (4, [2.0, 0.0, 0.0]),
                (5, [2.0, 1.0, 0.0]),
                (6, [1.5, 0.0, 0.0]),
            ],
        )],
        element_blocks: vec![
            (2, 1, 2, vec![(1, vec![1, 2, 3])]),
            (2, 1, quad_type, vec![(2, quad_nodes)]),
        ],
        ..Fixture::default()
    }
}

#[test]
fn several_kinds_in_one_body() {
    let e = parse_msh(mixed(3, vec![2, 4, 5, 3]).ascii().as_bytes(), &opts(2)).unwrap_err();
    assert_eq!(
        e,
        MeshError::MixedKinds {
            kinds: vec![
                ("3-node triangles".into(), 1),
                ("4-node quadrilaterals".into(), 1)
            ]
        }
    );
    assert!(
        e.to_string().contains("1 3-node triangles, 1 4-node"),
        "{e}"
    );
}

#[test]
fn second_order_elements_are_not_taken() {
    let mut f = mixed(3, vec![]);
    f.element_blocks = vec![(2, 1, 9, vec![(1, vec![1, 4, 5, 6, 3, 2])])];
    let e = parse_msh(f.ascii().as_bytes(), &opts(2)).unwrap_err();
    assert!(
        matches!(&e, MeshError::UnsupportedKind { count: 1, kind } if kind.contains("Tri6")),
        "{e:?}"
    );
    assert!(e.to_string().contains("Mesh.ElementOrder = 1"), "{e}");
}

#[test]
fn clockwise_triangle_is_inverted() {
    let mut f = mixed(3, vec![]);
    f.element_blocks = vec![(2, 1, 2, vec![(7, vec![1, 3, 2])])];
    let e = parse_msh(f.ascii().as_bytes(), &opts(2)).unwrap_err();
    let MeshError::Inverted { element, centroid } = e else {
        panic!("{e:?}")
    };
    assert_eq!(element, 7);
    assert!((centroid[0] - 2.0 / 3.0).abs() < 1e-15 && (centroid[1] - 1.0 / 3.0).abs() < 1e-15);
}

#[test]
fn pieces_touching_at_a_node_are_disconnected() {
    let mut f = mixed(3, vec![]);
    f.element_blocks = vec![(2, 1, 2, vec![(1, vec![1, 2, 3]), (2, vec![2, 4, 5])])];
    let text = f.ascii();
    let e = parse_msh(text.as_bytes(), &opts(2)).unwrap_err();
    assert_eq!(e, MeshError::Disconnected { pieces: 2 });
    let m = parse_msh(
        text.as_bytes(),
        &ImportOptions {
            allow_disconnected: true,
            ..opts(2)
        },
    )
    .unwrap();
    assert_eq!((m.pieces, m.unused_nodes), (2, 1));
}

#[test]
fn inconsistent_files() {
    let mut f = mixed(3, vec![]);
    f.element_blocks = vec![(2, 1, 2, vec![(1, vec![1, 2, 99])])];
    let e = parse_msh(f.ascii().as_bytes(), &opts(2)).unwrap_err();
    assert_eq!(
        e,
        MeshError::UnknownNode {
            element: 1,
            node: 99
        }
    );
    // Three triangles on the edge 1-2.
    let mut f = mixed(3, vec![]);
    f.node_blocks[0].2.push((7, [0.5, -1.0, 0.0]));
    f.element_blocks = vec![(
        2,
        1,
        2,
        vec![(1, vec![1, 2, 3]), (2, vec![2, 1, 7]), (3, vec![1, 2, 5])],
    )];
    let e = parse_msh(f.ascii().as_bytes(), &opts(2)).unwrap_err();
    assert_eq!(
        e,
        MeshError::NonManifold {
            cells: vec![1, 2, 3]
        }
    );
    // Node 100 in two blocks (sparse tags: mshio keeps them).
    let mut f = mixed(3, vec![]);
    f.element_blocks = vec![(2, 1, 2, vec![(1, vec![1, 2, 3])])];
    f.node_blocks[0].2.push((100, [5.0, 5.0, 0.0]));
    f.node_blocks.push((2, 2, vec![(100, [6.0, 5.0, 0.0])]));
    let e = parse_msh(f.binary().as_slice(), &opts(2)).unwrap_err();
    assert_eq!(e, MeshError::DuplicateNode { tag: Some(100) });
    // A coordinate that is not a number (binary: any bit pattern).
    let mut f = mixed(3, vec![]);
    f.element_blocks = vec![(2, 1, 2, vec![(1, vec![1, 2, 3])])];
    f.node_blocks[0].2[1].1[0] = f64::NAN;
    let e = parse_msh(f.binary().as_slice(), &opts(2)).unwrap_err();
    assert_eq!(e, MeshError::NonFinite { node: 2 });
}

#[test]
fn options_out_of_range() {
    let e = parse_msh(TRI_SQUARE.as_bytes(), &opts(1)).unwrap_err();
    assert!(matches!(e, MeshError::Options(_)));
    let o = ImportOptions {
        unit: -1.0,
        ..opts(2)
    };
    assert!(matches!(
        parse_msh(TRI_SQUARE.as_bytes(), &o),
        Err(MeshError::Options(_))
    ));
}

/// No prefix of a file and no single-byte change makes the reader panic (its
/// own code or mshio's, which it catches): each gives a mesh or an error.
#[test]
fn damaged_files_give_errors_not_panics() {
    let files = [
        TRI_SQUARE.as_bytes().to_vec(),
        quad_grid(true).binary(),
        hex(false).binary(),
    ];
    for bytes in &files {
        for cut in 0..bytes.len() {
            let _ = parse_msh(&bytes[..cut], &opts(2));
        }
        for at in 0..bytes.len() {
            for v in [b'0', b'9', b'-', b' ', 0xff] {
                let mut b = bytes.clone();
                b[at] = v;
                let _ = parse_msh(&b, &opts(2));
                let _ = parse_msh(&b, &opts(3));
            }
        }
    }
}

/// `n = (b - a) x (c - a)` of a facet's first three nodes.
fn facet_normal(m: &ImportedMesh, f: &[usize]) -> [f64; 3] {
    let (a, b, c) = (m.nodes[f[0]], m.nodes[f[1]], m.nodes[f[2]]);
    let (u, v) = (sub(b, a), sub(c, a));
    [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ]
}

/// Files written by another program (meshio's MSH 4.1 writer, see
/// tests/meshes/make_cube_tets.py): ASCII and binary read alike, the cube
/// comes back whole (volume 1e-6 m^3), every boundary facet faces away from
/// its centre, and `bottom` (written facing in) comes back facing -z.
#[test]
fn files_written_by_meshio() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/meshes");
    let o = ImportOptions {
        unit: 1e-3,
        region: Some("cube"),
        ..opts(3)
    };
    let ascii = read_msh(&dir.join("cube_tets_ascii.msh"), &o).unwrap();
    let binary = read_msh(&dir.join("cube_tets_binary.msh"), &o).unwrap();
    assert_eq!(ascii, binary);
    let m = ascii;
    assert_eq!(
        (m.kind, m.nodes.len(), m.cells.len()),
        (CellKind::Tet4, 8, 6)
    );
    assert_eq!(m.nodes[6], [0.01, 0.01, 0.01]);
    let volume: f64 = m
        .cells
        .iter()
        .map(|c| {
            let p: Vec<[f64; 3]> = c.iter().map(|&n| m.nodes[n]).collect();
            det3(sub(p[1], p[0]), sub(p[2], p[0]), sub(p[3], p[0])) / 6.0
        })
        .sum();
    assert!((volume - 1e-6).abs() < 1e-18, "{volume}");
    assert_eq!(m.boundary.len(), 12);
    for f in &m.boundary {
        let n = facet_normal(&m, f);
        let a = m.nodes[f[0]];
        let out: f64 = (0..3).map(|k| n[k] * (a[k] - 0.005)).sum();
        assert!(out > 0.0, "{f:?} faces in");
    }
    assert_eq!(m.faces.len(), 1);
    assert_eq!(m.faces[0].name, "bottom");
    assert_eq!(m.faces[0].facets.len(), 2);
    for f in &m.faces[0].facets {
        assert!(facet_normal(&m, f)[2] < 0.0, "{f:?}");
    }
}
