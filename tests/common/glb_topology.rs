//! Reading a glb's triangles back to check that each node's mesh is closed.

/// Per node with a mesh: its name and whether every undirected edge of its triangles is shared
/// by exactly two of them.
pub fn closed_nodes(glb: &[u8]) -> Vec<(String, bool)> {
    // The gltf crate refuses files that require KHR_mesh_quantization when it validates; the
    // Khronos validator is what checks our files, so read them without.
    let gltf = gltf::Gltf::from_slice_without_validation(glb).expect("glb parses");
    let blob = gltf.blob.as_deref().expect("a BIN chunk");
    gltf.nodes()
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

/// Per node with a mesh, of a glb with f32 positions (`compression: none`): its name, its
/// zero-area triangles (corners' cross product exactly zero, in f64) and its vertices at the
/// position of another (bit for bit).
pub fn degenerate_nodes(glb: &[u8]) -> Vec<(String, usize, usize)> {
    let gltf = gltf::Gltf::from_slice_without_validation(glb).expect("glb parses");
    let blob = gltf.blob.as_deref().expect("a BIN chunk");
    gltf.nodes()
        .filter_map(|node| {
            let prim = node.mesh()?.primitives().next()?;
            let reader = prim.reader(|_| Some(blob));
            let positions: Vec<[f32; 3]> = reader.read_positions().expect("f32 positions").collect();
            let indices: Vec<u32> = reader.read_indices()?.into_u32().collect();
            let p = |i: u32| positions[i as usize].map(f64::from);
            let zero = indices
                .chunks_exact(3)
                .filter(|t| {
                    let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
                    let (u, v) = ([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]]);
                    [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]] == [0.0; 3]
                })
                .count();
            let mut keys: Vec<[u32; 3]> = positions.iter().map(|q| q.map(|c| (c + 0.0).to_bits())).collect();
            keys.sort_unstable();
            let duplicates = keys.windows(2).filter(|w| w[0] == w[1]).count();
            Some((node.name().unwrap_or_default().to_string(), zero, duplicates))
        })
        .collect()
}
