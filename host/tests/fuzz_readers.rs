//! Property tests of the host's file readers: Gmsh meshes (versions 1, 2.2 and 4.1),
//! `scene.toml` (read alone, and loaded with its mesh and tracks), `scenario.toml`, and the
//! CSV and OBJ files of a scene, the OpenCV camera calibration in YAML and XML, and VTU meshes.
//! Valid files are damaged (a token replaced by junk, lines deleted, repeated or cut short,
//! random text inserted) and random text is fed whole: every input gives a value or an error
//! naming the file (and, for the project's own readers, a line within it), never a panic.
//!
//! The case count per property is 256 in CI; `INCISE_FUZZ_CASES=100000 cargo test -p incise
//! --release --test fuzz_readers` runs more.

use std::path::{Path, PathBuf};

use incise::generate::scenario::Scenario;
use incise::msh::parse_msh;
use incise::scene::{
    Scene, SceneError, SceneFile, read_cut_csv, read_obj, read_points_csv, read_tracks,
};
use proptest::prelude::*;
use proptest::sample::Index;

fn cases() -> u32 {
    std::env::var("INCISE_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(256)
}

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures/band-side-cut")
        .join(name)
}

fn read(name: &str) -> String {
    std::fs::read_to_string(fixture(name)).unwrap()
}

/// What a damaged file may hold instead of a token: numbers at and beyond every bound, values
/// of the wrong kind, section markers and separators.
const JUNK: &[&str] = &[
    "",
    "0",
    "1",
    "-1",
    "4",
    "0.5",
    "-0",
    "x",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e999",
    "1e10",
    "10000000000",
    "4294967296",
    "18446744073709551616",
    "-9223372036854775809",
    "100000",
    "99999",
    "$Nodes",
    "$EndNodes",
    "$Elements",
    "$EndElements",
    "$NOD",
    "$ELM",
    "[capacities]",
    "[ground_truth]",
    "\"s\"",
    "[",
    "]",
    "=",
    ",",
    "1,2",
    "v",
    "f",
    "\u{0}",
    "é",
];

/// One way of damaging a text.
#[derive(Clone, Debug)]
enum Damage {
    /// Replace a token (split at spaces, commas and `=`) of a line by junk.
    Token(Index, Index, usize),
    /// Delete a line.
    Delete(Index),
    /// Repeat a line.
    Repeat(Index),
    /// Cut the text short at a character.
    Truncate(Index),
    /// Insert a line of random text.
    Insert(Index, String),
}

fn damage() -> impl Strategy<Value = Damage> {
    prop_oneof![
        4 => (any::<Index>(), any::<Index>(), 0..JUNK.len()).prop_map(|(l, t, j)| Damage::Token(l, t, j)),
        1 => any::<Index>().prop_map(Damage::Delete),
        1 => any::<Index>().prop_map(Damage::Repeat),
        1 => any::<Index>().prop_map(Damage::Truncate),
        1 => (any::<Index>(), "\\PC{0,40}").prop_map(|(l, s)| Damage::Insert(l, s)),
    ]
}

/// `text` with every damage of `damages` done in turn.
fn damaged(text: &str, damages: &[Damage]) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    for d in damages {
        if lines.is_empty() {
            lines.push(String::new());
        }
        match d {
            Damage::Token(l, t, j) => {
                let i = l.index(lines.len());
                let line = &mut lines[i];
                let tokens: Vec<&str> = line.split_inclusive([' ', ',', '=']).collect();
                let k = t.index(tokens.len().max(1));
                let mut out = String::new();
                for (i, tok) in tokens.iter().enumerate() {
                    if i == k {
                        // Keep the separator so that the line keeps its shape.
                        let sep = tok.chars().last().filter(|c| [' ', ',', '='].contains(c));
                        out.push_str(JUNK[*j]);
                        if let Some(c) = sep {
                            out.push(c);
                        }
                    } else {
                        out.push_str(tok);
                    }
                }
                if tokens.is_empty() {
                    out.push_str(JUNK[*j]);
                }
                *line = out;
            }
            Damage::Delete(l) => {
                let i = l.index(lines.len());
                lines.remove(i);
            }
            Damage::Repeat(l) => {
                let i = l.index(lines.len());
                let line = lines[i].clone();
                lines.insert(i, line);
            }
            Damage::Truncate(c) => {
                let text = lines.join("\n");
                let chars: Vec<(usize, char)> = text.char_indices().collect();
                let cut = chars
                    .get(c.index(chars.len().max(1)))
                    .map_or(0, |&(i, _)| i);
                lines = text[..cut].lines().map(str::to_owned).collect();
            }
            Damage::Insert(l, s) => {
                let i = l.index(lines.len() + 1);
                lines.insert(i, s.clone());
            }
        }
    }
    let mut out = lines.join("\n");
    out.push('\n');
    out
}

fn damages() -> impl Strategy<Value = Vec<Damage>> {
    prop::collection::vec(damage(), 1..6)
}

/// An error names `file` and a line of `text` (or none: 0).
fn names_file_and_line(e: &SceneError, file: &Path, text: &str) {
    assert_eq!(e.file, file, "{e}");
    assert!(e.line <= text.lines().count() + 1, "line {} of {e}", e.line);
    assert!(!e.message.is_empty());
}

/// A Gmsh 4.1 file of one tetrahedron and a spare node, in two entity blocks.
const V41: &str = "$MeshFormat
4.1 0 8
$EndMeshFormat
$Nodes
2 5 1 5
3 1 0 4
1
2
3
4
0 0 0
1 0 0
0 1 0
0 0 1
3 2 0 1
5
1 1 1
$EndNodes
$Elements
1 1 1 1
3 1 4 1
1 1 2 3 4
$EndElements
";

/// The same in version 1.
const V1: &str = "$NOD
5
1 0 0 0
2 1 0 0
3 0 1 0
4 0 0 1
5 1 1 1
$ENDNOD
$ELM
1
1 4 1 1 4 1 2 3 4
$ENDELM
";

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), ..ProptestConfig::default() })]

    #[test]
    fn damaged_meshes_give_errors_not_panics(
        which in 0..3usize,
        damages in damages(),
    ) {
        let band = read("model.msh");
        let text = damaged([band.as_str(), V41, V1][which], &damages);
        if let Err(e) = parse_msh(&text, "m.msh") {
            prop_assert_eq!(&e.file, "m.msh");
            prop_assert!(e.line <= text.lines().count() + 1, "{}", e);
        }
    }

    #[test]
    fn random_text_is_no_mesh(
        header in prop_oneof![Just(""), Just("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n"),
            Just("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n"), Just("$NOD\n")],
        body in "\\PC{0,300}",
    ) {
        let text = format!("{header}{body}");
        let _ = parse_msh(&text, "m.msh");
    }

    #[test]
    fn damaged_scene_files_give_errors_naming_the_line(damages in damages()) {
        let text = damaged(&read("scene.toml"), &damages);
        let file = Path::new("scene.toml");
        if let Err(e) = SceneFile::parse(&text, file) {
            names_file_and_line(&e, file, &text);
        }
    }

    #[test]
    fn damaged_scenarios_give_errors_naming_the_line(damages in damages()) {
        let text = damaged(&read("scenario.toml"), &damages);
        let file = Path::new("scenario.toml");
        if let Err(e) = Scenario::parse(&text, file) {
            names_file_and_line(&e, file, &text);
        }
    }

    #[test]
    fn damaged_tracks_give_errors_naming_the_line(damages in damages()) {
        let text = damaged(&read("tracks.csv"), &damages);
        let file = Path::new("tracks.csv");
        match read_tracks(&text, file) {
            Ok(frames) => prop_assert!(!frames.is_empty()),
            Err(e) => names_file_and_line(&e, file, &text),
        }
    }

    #[test]
    fn damaged_ground_truth_gives_errors_naming_the_line(
        which in 0..3usize,
        damages in damages(),
    ) {
        let name = ["gt/targets.csv", "gt/cut.csv", "gt/surface.obj"][which];
        let text = damaged(&read(name), &damages);
        let file = Path::new(name);
        let result = match which {
            0 => read_points_csv(&text, file).map(drop),
            1 => read_cut_csv(&text, file).map(drop),
            _ => read_obj(&text, file).map(drop),
        };
        if let Err(e) = result {
            names_file_and_line(&e, file, &text);
        }
    }

    #[test]
    fn random_rows_are_no_tracks(rows in prop::collection::vec(
        ("[0-9-]{0,7}", "[0-9a-z.-]{0,11}", "[0-9eE.+-]{0,8}", "[0-9naif.-]{0,8}"), 0..20,
    )) {
        let mut text = String::from("frame,id,u,v\n");
        for (f, i, u, v) in &rows {
            text.push_str(&format!("{f},{i},{u},{v}\n"));
        }
        let _ = read_tracks(&text, Path::new("t.csv"));
        let _ = read_points_csv(&text, Path::new("t.csv"));
        let _ = read_cut_csv(&text, Path::new("t.csv"));
    }
}

proptest! {
    // Each case writes a scene directory and loads it with its mesh: fewer cases.
    #![proptest_config(ProptestConfig {
        cases: (cases() / 8).max(1),
        ..ProptestConfig::default()
    })]

    #[test]
    fn damaged_scenes_load_or_give_errors(which in 0..3usize, damages in damages()) {
        let tmp = tempfile::tempdir().unwrap();
        let names = ["scene.toml", "model.msh", "tracks.csv"];
        for (k, name) in names.iter().enumerate() {
            let text = read(name);
            let text = if k == which { damaged(&text, &damages) } else { text };
            std::fs::write(tmp.path().join(name), text).unwrap();
        }
        if let Ok(scene) = Scene::load(tmp.path()) {
            prop_assert!(!scene.frames.is_empty());
            let n = scene.rest.len();
            prop_assert!(scene.file.model.fixed.iter().all(|&f| (f as usize) < n));
        }
    }
}

/// The camera calibration (OpenCV's YAML and XML, read by the host's own reader: OpenCV 4.6's
/// `FileStorage` crashed on some of these damaged files): every damaged or random file gives a
/// calibration whose invariants hold or an error naming the file and a line within it.
mod calibration {
    use super::*;
    use incise::calibration::{EXAMPLE_XML as XML, EXAMPLE_YAML as YAML, read_calibration};

    fn check(text: &str, ext: &str) {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join(format!("camera.{ext}"));
        std::fs::write(&path, text).unwrap();
        match read_calibration(&path) {
            Ok(c) => {
                let k = c.camera_matrix;
                assert!(k.iter().flatten().all(|x| x.is_finite()));
                assert!(k[0][0] > 0.0 && k[1][1] > 0.0 && k[2] == [0.0, 0.0, 1.0]);
                assert!([0, 4, 5, 8, 12, 14].contains(&c.dist_coeffs.len()));
                assert!(c.dist_coeffs.iter().all(|x| x.is_finite()));
            }
            Err(e) => names_file_and_line(&e, &path, text),
        }
    }

    #[test]
    fn the_undamaged_files_read() {
        for (text, ext) in [(YAML, "yml"), (XML, "xml")] {
            let tmp = tempfile::tempdir().unwrap();
            let path = tmp.path().join(format!("camera.{ext}"));
            std::fs::write(&path, text).unwrap();
            let c = read_calibration(&path).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!((c.camera_matrix[1][1], c.dist_coeffs.len()), (510.0, 5));
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: cases(), ..ProptestConfig::default() })]

        #[test]
        fn damaged_calibrations_give_errors_naming_the_line(
            xml in any::<bool>(),
            damages in damages(),
        ) {
            let (text, ext) = if xml { (XML, "xml") } else { (YAML, "yml") };
            check(&damaged(text, &damages), ext);
        }

        #[test]
        fn random_text_is_no_calibration(xml in any::<bool>(), body in "\\PC{0,200}") {
            let (head, ext) = if xml {
                ("<?xml version=\"1.0\"?>\n<opencv_storage>\n", "xml")
            } else {
                ("%YAML:1.0\n---\n", "yml")
            };
            check(&format!("{head}{body}"), ext);
        }
    }
}

/// The VTK XML unstructured grid (`.vtu`, read through `vtkio`): damaged or random files give a
/// mesh whose promises hold or an error naming the file; never a panic.
mod vtu {
    use super::*;
    use incise::vtu::{read_vtu, write_vtu};

    fn valid() -> String {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("m.vtu");
        let points = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 1.0, 1.0],
        ];
        write_vtu(&path, &points, &[[0, 1, 2, 3], [1, 2, 3, 4]], &[], &[]).unwrap();
        std::fs::read_to_string(&path).unwrap()
    }

    fn check(text: &str) {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("m.vtu");
        std::fs::write(&path, text).unwrap();
        match read_vtu(&path) {
            Ok(m) => {
                assert!(!m.tets.is_empty());
                assert!(m.nodes.iter().flatten().all(|c| c.is_finite()));
                assert!(
                    m.tets
                        .iter()
                        .flatten()
                        .all(|&v| (v as usize) < m.nodes.len())
                );
            }
            Err(e) => assert_eq!(e.file, path.display().to_string(), "{e}"),
        }
    }

    #[test]
    fn the_undamaged_file_reads() {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("m.vtu");
        std::fs::write(&path, valid()).unwrap();
        let m = read_vtu(&path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((m.nodes.len(), m.tets.len()), (5, 2));
    }

    #[test]
    fn huge_counts_are_refused_without_allocating_them() {
        let text = valid();
        for (from, to) in [
            ("NumberOfPoints=\"5\"", "NumberOfPoints=\"1000000000\""),
            ("NumberOfCells=\"2\"", "NumberOfCells=\"1000000000\""),
            (
                "NumberOfPoints=\"5\"",
                "NumberOfPoints=\"18446744073709551615\"",
            ),
        ] {
            assert!(text.contains(from), "{from}");
            let tmp = tempfile::tempdir().unwrap();
            let path = tmp.path().join("m.vtu");
            std::fs::write(&path, text.replace(from, to)).unwrap();
            let _ = read_vtu(&path);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: cases(), ..ProptestConfig::default() })]

        #[test]
        fn damaged_vtu_files_give_errors_not_panics(damages in damages()) {
            check(&damaged(&valid(), &damages));
        }

        #[test]
        fn random_text_is_no_vtu(body in "\\PC{0,300}") {
            check(&format!("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\">\n{body}"));
        }
    }
}
