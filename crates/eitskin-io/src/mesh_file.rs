//! Mesh files (JSON), in the shape of EIDORS' exported `mesh.json`:
//!
//! ```json
//! { "units": "m", "index_base": 0,
//!   "nodes": [[x, y], …], "elems": [[n0, n1, n2], …],
//!   "electrodes": [{ "index": 0, "nodes": [n, …] }, …] }
//! ```
//! Node indices count from `index_base` (0 unless given); electrode k of the array is
//! electrode k + 1. Coordinates are in `units` ("m" unless given, or "mm"). Other keys
//! (centroids, areas, ground node) are ignored, so EIDORS' file loads as it is.

use std::path::Path;

use eitskin::Mesh;
use serde::{Deserialize, Serialize};

use crate::Error;

#[derive(Debug, Serialize, Deserialize)]
struct MeshJson {
    #[serde(default = "metre")]
    units: String,
    #[serde(default)]
    index_base: usize,
    nodes: Vec<[f64; 2]>,
    elems: Vec<[usize; 3]>,
    electrodes: Vec<ElectrodeJson>,
}

#[derive(Debug, Serialize, Deserialize)]
struct ElectrodeJson {
    #[serde(default)]
    index: usize,
    nodes: Vec<usize>,
}

fn metre() -> String {
    "m".into()
}

/// Reads a mesh file.
pub fn read_mesh(path: &Path) -> Result<Mesh, Error> {
    parse_mesh(&crate::read_text(path)?).map_err(|e| e.in_file(path))
}

/// Parses mesh JSON and checks the mesh.
pub fn parse_mesh(text: &str) -> Result<Mesh, Error> {
    let file: MeshJson = serde_json::from_str(text).map_err(|e| Error::Json { path: None, message: e.to_string() })?;
    let scale = match file.units.as_str() {
        "m" => 1.0,
        "mm" => 1e-3,
        other => {
            return Err(Error::Key {
                path: None,
                key: "units",
                reason: format!("must be \"m\" or \"mm\", got \"{other}\""),
            })
        }
    };
    let base = file.index_base;
    if base > 1 {
        return Err(Error::Key { path: None, key: "index_base", reason: format!("must be 0 or 1, got {base}") });
    }
    // Every index is checked in the file's own numbering, so that a message quotes it as written.
    let (lo, hi) = (base, file.nodes.len() + base);
    let numbering = || match file.nodes.len() {
        0 => "the file has no nodes".to_string(),
        n => format!("with index_base = {base} the {n} nodes are numbered {lo} to {}", hi - 1),
    };
    for (k, t) in file.elems.iter().enumerate() {
        if let Some(n) = t.iter().find(|n| !(lo..hi).contains(*n)) {
            let reason = format!("triangle {} names node {n}, but {}", k + 1, numbering());
            return Err(Error::Key { path: None, key: "elems", reason });
        }
    }
    for (k, e) in file.electrodes.iter().enumerate() {
        if let Some(n) = e.nodes.iter().find(|n| !(lo..hi).contains(*n)) {
            let reason = format!("electrode {} names node {n}, but {}", k + 1, numbering());
            return Err(Error::Key { path: None, key: "electrodes", reason });
        }
    }
    let nodes = file.nodes.iter().map(|p| p.map(|c| c * scale)).collect();
    let triangles = file.elems.iter().map(|t| t.map(|n| n - base)).collect();
    let electrodes = file.electrodes.iter().map(|e| e.nodes.iter().map(|&n| n - base).collect()).collect();
    Ok(Mesh::new(nodes, triangles, electrodes)?)
}

/// The mesh as JSON (metres, 0-based indices), readable by [`parse_mesh`].
pub fn mesh_to_json(mesh: &Mesh) -> String {
    let file = MeshJson {
        units: metre(),
        index_base: 0,
        nodes: mesh.nodes().to_vec(),
        elems: mesh.triangles().to_vec(),
        electrodes: mesh
            .electrodes()
            .iter()
            .enumerate()
            .map(|(index, nodes)| ElectrodeJson { index, nodes: nodes.clone() })
            .collect(),
    };
    // Serialising finite numbers and indices cannot fail.
    serde_json::to_string(&file).unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;
    use eitskin::SensorSpec;

    #[test]
    fn written_mesh_reads_back_equal() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 300;
        let mesh = spec.mesh().unwrap();
        assert!(parse_mesh(&mesh_to_json(&mesh)).unwrap() == mesh, "the mesh changed on the way");
    }

    #[test]
    fn bad_mesh_says_where() {
        let text = r#"{"nodes": [[0,0],[1,0],[0,1]], "elems": [[0,1,3]], "electrodes": []}"#;
        let err = parse_mesh(text).unwrap_err();
        assert_eq!(
            crate::full_message(&err),
            "`elems` triangle 1 names node 3, but with index_base = 0 the 3 nodes are numbered 0 to 2"
        );
        // A file counted from 1 read as counted from 0 (or the other way) names node 0: said
        // so in the file's own numbering, not as node 18446744073709551615.
        let text =
            r#"{"index_base": 1, "nodes": [[0,0],[1,0],[0,1]], "elems": [[1,2,3]], "electrodes": [{"nodes": [0, 1]}]}"#;
        assert_eq!(
            crate::full_message(&parse_mesh(text).unwrap_err()),
            "`electrodes` electrode 1 names node 0, but with index_base = 1 the 3 nodes are numbered 1 to 3"
        );
        let err = parse_mesh(r#"{"nodes": [], "elems": []}"#).unwrap_err();
        assert!(err.to_string().contains("missing field `electrodes`"), "{err}");
    }
}
