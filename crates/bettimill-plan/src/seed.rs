//! Seeds and the manifest's identity: the canonical JSON and its hash, and the seeds every
//! sample, attempt and shard shuffle derive from it (see the crate docs for the domains).

use bettimill_manifest::Manifest;
use bettimill_shapes::Family;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// The manifest's canonical JSON: every field, defaults filled in, fixed key order, the
/// classes as resolved constructions. Comments, whitespace and the order of keys in the
/// file do not change it.
pub fn canonical_json(manifest: &Manifest, classes: &[Family]) -> String {
    let head = manifest.json_without_classes();
    let head = head
        .strip_suffix("[]}")
        .expect("`classes` is the manifest's last serialised field");
    let classes = serde_json::to_string(classes).expect("families always serialise");
    format!("{head}{classes}}}")
}

/// blake3 of [`canonical_json`], as 64 hex digits. Identifies the dataset.
pub fn manifest_hash(manifest: &Manifest, classes: &[Family]) -> String {
    blake3::hash(canonical_json(manifest, classes).as_bytes())
        .to_hex()
        .to_string()
}

/// Derives a 32-byte seed in the named domain from `parts`.
pub fn derive_seed(domain: &str, parts: &[&[u8]]) -> [u8; 32] {
    let mut hasher = blake3::Hasher::new_derive_key(domain);
    for part in parts {
        hasher.update(part);
    }
    *hasher.finalize().as_bytes()
}

/// The RNG for regeneration attempt `attempt` of a sample.
pub fn attempt_rng(sample_seed: &[u8; 32], attempt: u32) -> ChaCha8Rng {
    ChaCha8Rng::from_seed(derive_seed(
        "bettimill attempt seed v1",
        &[sample_seed, &attempt.to_le_bytes()],
    ))
}
