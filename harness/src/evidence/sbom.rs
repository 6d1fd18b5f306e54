//! The software bill of materials: a CycloneDX 1.5 JSON document written from `cargo metadata`
//! (the resolved graph, licences) and `Cargo.lock` (each crate's registry checksum), for the
//! host workspace and the firmware's own workspace.
//!
//! Written here rather than by `cargo-cyclonedx` or `cargo-auditable`: both are extra cargo
//! subcommands every machine and CI job would have to build and install first, and
//! `cargo-auditable` changes the binaries' bytes (it embeds the dependency list), which would
//! make the rig's artifacts differ from a plain `cargo build` of the same tree. The part of the
//! format used here is small: components with a `pkg:cargo` purl, SHA-256 and licence, and the
//! dependency graph.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

use anyhow::{Context, Result, bail};
use serde_json::{Value, json};

use crate::record::sha256_bytes;

/// File name of the SBOM in an evidence folder.
pub const SBOM_FILE: &str = "sbom.cdx.json";

/// `cargo metadata` of the workspace at `dir`, as JSON.
fn metadata(dir: &Path) -> Result<Value> {
    let out = Command::new("cargo")
        .args(["metadata", "--format-version", "1", "--locked"])
        .current_dir(dir)
        .output()
        .with_context(|| format!("cannot run cargo metadata in {}", dir.display()))?;
    if !out.status.success() {
        bail!(
            "cargo metadata in {} failed: {}",
            dir.display(),
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    Ok(serde_json::from_slice(&out.stdout)?)
}

/// Registry checksums by (name, version), from a `Cargo.lock`.
fn checksums(lock: &Path) -> Result<BTreeMap<(String, String), String>> {
    let text =
        std::fs::read_to_string(lock).with_context(|| format!("cannot read {}", lock.display()))?;
    let value: toml::Value =
        toml::from_str(&text).with_context(|| format!("{}: not TOML", lock.display()))?;
    let mut out = BTreeMap::new();
    for p in value
        .get("package")
        .and_then(|p| p.as_array())
        .into_iter()
        .flatten()
    {
        if let (Some(n), Some(v), Some(c)) = (
            p.get("name").and_then(|x| x.as_str()),
            p.get("version").and_then(|x| x.as_str()),
            p.get("checksum").and_then(|x| x.as_str()),
        ) {
            out.insert((n.to_owned(), v.to_owned()), c.to_owned());
        }
    }
    Ok(out)
}

/// Components and dependency edges of one workspace (`dir` holds its Cargo.toml and
/// Cargo.lock), keyed by bom-ref.
fn workspace(
    dir: &Path,
    components: &mut BTreeMap<String, Value>,
    edges: &mut BTreeMap<String, Vec<String>>,
) -> Result<()> {
    let meta = metadata(dir)?;
    let sums = checksums(&dir.join("Cargo.lock"))?;
    let mut refs = BTreeMap::new();
    for p in meta["packages"].as_array().into_iter().flatten() {
        let (Some(name), Some(version), Some(id)) =
            (p["name"].as_str(), p["version"].as_str(), p["id"].as_str())
        else {
            continue;
        };
        let local = p["source"].is_null();
        let purl = format!("pkg:cargo/{name}@{version}");
        let bom_ref = if local {
            format!("{purl}?local")
        } else {
            purl.clone()
        };
        refs.insert(id.to_owned(), bom_ref.clone());
        let mut c = json!({
            "type": if local { "application" } else { "library" },
            "bom-ref": bom_ref,
            "name": name,
            "version": version,
            "purl": purl,
            "scope": "required",
        });
        if let Some(l) = p["license"].as_str() {
            c["licenses"] = json!([{ "expression": l }]);
        }
        if let Some(sum) = sums.get(&(name.to_owned(), version.to_owned())) {
            c["hashes"] = json!([{ "alg": "SHA-256", "content": sum }]);
        }
        components.insert(bom_ref, c);
    }
    for node in meta["resolve"]["nodes"].as_array().into_iter().flatten() {
        let Some(from) = node["id"].as_str().and_then(|id| refs.get(id)) else {
            continue;
        };
        let to = edges.entry(from.clone()).or_default();
        for d in node["dependencies"].as_array().into_iter().flatten() {
            if let Some(r) = d.as_str().and_then(|id| refs.get(id)) {
                to.push(r.clone());
            }
        }
        to.sort();
        to.dedup();
    }
    Ok(())
}

/// The SBOM of the host workspace at `repo` and the firmware crate at `firmware`, for the
/// build of `commit` (`timestamp` RFC 3339: the build's, so the document is reproducible too).
pub fn sbom(repo: &Path, firmware: &Path, commit: &str, timestamp: &str) -> Result<Value> {
    let mut components = BTreeMap::new();
    let mut edges = BTreeMap::new();
    workspace(repo, &mut components, &mut edges)?;
    workspace(firmware, &mut components, &mut edges)?;
    // A serial number derived from the commit: same build, same document.
    let h = sha256_bytes(format!("sbom {commit}").as_bytes());
    let serial = format!(
        "urn:uuid:{}-{}-4{}-8{}-{}",
        &h[0..8],
        &h[8..12],
        &h[13..16],
        &h[17..20],
        &h[20..32]
    );
    Ok(json!({
        "bomFormat": "CycloneDX",
        "specVersion": "1.5",
        "serialNumber": serial,
        "version": 1,
        "metadata": {
            "timestamp": timestamp,
            "tools": { "components": [{
                "type": "application",
                "name": env!("CARGO_PKG_NAME"),
                "version": env!("CARGO_PKG_VERSION"),
            }]},
            "component": {
                "type": "application",
                "bom-ref": "rig-build",
                "name": "c2-rig",
                "version": commit,
            },
        },
        "components": components.into_values().collect::<Vec<_>>(),
        "dependencies": edges
            .into_iter()
            .map(|(r, d)| json!({ "ref": r, "dependsOn": d }))
            .collect::<Vec<_>>(),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_workspace_sbom_lists_locked_crates_with_their_checksums() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let bom = sbom(
            &root,
            &root.join(crate::devices::FIRMWARE.dir),
            "0123",
            "2026-01-01T00:00:00Z",
        )
        .unwrap();
        let comps = bom["components"].as_array().unwrap();
        let find = |name: &str| comps.iter().find(|c| c["name"] == name);
        let sha2 = find("sha2").expect("sha2 is a dependency of the rig");
        assert_eq!(sha2["hashes"][0]["alg"], "SHA-256");
        assert_eq!(sha2["hashes"][0]["content"].as_str().unwrap().len(), 64);
        assert!(
            find("atsamd-hal").is_some(),
            "the firmware's crates are in too"
        );
        assert!(
            find("harness").unwrap()["purl"]
                .as_str()
                .unwrap()
                .starts_with("pkg:cargo/harness@")
        );
        // Every edge points at a listed component.
        let refs: Vec<&Value> = comps.iter().map(|c| &c["bom-ref"]).collect();
        for d in bom["dependencies"].as_array().unwrap() {
            for to in d["dependsOn"].as_array().unwrap() {
                assert!(refs.contains(&to), "{to} not a component");
            }
        }
    }
}
