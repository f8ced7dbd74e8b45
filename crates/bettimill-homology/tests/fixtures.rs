//! Betti numbers of the committed fixtures must match what GUDHI and CubicalRipser said
//! (fixtures/make_fixtures.py wrote them; this test needs no Python).

use bettimill_grid::npy;
use std::path::Path;

#[test]
fn fixtures_match_gudhi_and_cubicalripser() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures");
    let text = std::fs::read_to_string(dir.join("expected.json")).expect("expected.json");
    let expected: serde_json::Value = serde_json::from_str(&text).expect("valid JSON");
    let images = expected["images"].as_object().expect("an images map");
    assert!(images.len() >= 20, "only {} fixtures", images.len());
    for (name, entry) in images {
        let image = npy::read_path(&dir.join(format!("{name}.npy")), true)
            .unwrap_or_else(|e| panic!("{name}: {e}"))
            .image;
        let shape: Vec<usize> = entry["shape"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap() as usize)
            .collect();
        assert_eq!(image.shape(), &shape[..], "{name}");
        let betti: Vec<u64> = entry["betti"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap())
            .collect();
        let found = bettimill_homology::topology(&image);
        assert_eq!(found.betti, betti, "{name}");
        if image.len() <= 2000 {
            assert_eq!(
                bettimill_homology::reference::topology(&image),
                found,
                "{name}"
            );
        }
    }
}
