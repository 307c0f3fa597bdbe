//! Reading a glb's triangles back to check that each node's mesh is closed.

/// Per node with a mesh: its name and whether every undirected edge of its triangles is shared
/// by exactly two of them.
pub fn closed_nodes(glb: &[u8]) -> Vec<(String, bool)> {
    // The gltf crate refuses files that require KHR_mesh_quantization when it validates; the
    // Khronos validator is what checks our files, so read them without.
    let gltf = gltf::Gltf::from_slice_without_validation(glb).expect("glb parses");
    let blob = gltf.blob.as_deref().expect("a BIN chunk");
    // The scene's nodes: their levels of detail (MSFT_lod) are nodes outside it.
    gltf.default_scene()
        .expect("a default scene")
        .nodes()
        .filter_map(|node| {
            let mesh = node.mesh()?;
            let prim = mesh.primitives().next()?;
            let reader = prim.reader(|_| Some(blob));
            let indices: Vec<u32> = reader.read_indices()?.into_u32().collect();
            let mut edges: Vec<(u32, u32)> = indices
                .chunks_exact(3)
                .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
                .map(|(a, b)| (a.min(b), a.max(b)))
                .collect();
            edges.sort_unstable();
            let closed = !edges.is_empty() && edges.chunk_by(|a, b| a == b).all(|run| run.len() == 2);
            Some((node.name().unwrap_or_default().to_string(), closed))
        })
        .collect()
}
