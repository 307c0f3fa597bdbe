//! The playground's bundle: committed in `web/dist`, built from `web/src` (and the presets in
//! `api/`), embedded in the binary and served at `/`.

mod common;

use std::path::{Path, PathBuf};

use common::server::TestServer;
use sha2::{Digest, Sha256};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let p = entry.unwrap().path();
        if p.is_dir() {
            walk(&p, out);
        } else {
            out.push(p);
        }
    }
}

/// The same hash as `web/scripts/source-hash.mjs` (written by `npm run build`), computed here
/// without Node: for each source file in path order, "<path>\n<sha256 hex>\n", hashed.
fn source_hash() -> String {
    let root = repo();
    let mut files = Vec::new();
    walk(&root.join("web/src"), &mut files);
    for n in ["index.html", "vite.config.ts", "tsconfig.json", "package-lock.json"] {
        files.push(root.join("web").join(n));
    }
    for kind in std::fs::read_dir(root.join("api")).unwrap() {
        let dir = kind.unwrap().path();
        if dir.is_dir() {
            for f in std::fs::read_dir(&dir).unwrap() {
                let f = f.unwrap().path();
                if f.extension().is_some_and(|e| e == "json") {
                    files.push(f);
                }
            }
        }
    }
    let mut rel: Vec<String> =
        files.iter().map(|f| f.strip_prefix(&root).unwrap().to_string_lossy().replace('\\', "/")).collect();
    rel.sort();
    let mut h = Sha256::new();
    for r in rel {
        let bytes = std::fs::read(root.join(&r)).unwrap();
        h.update(format!("{r}\n{:x}\n", Sha256::digest(&bytes)));
    }
    format!("{:x}", h.finalize())
}

#[test]
fn the_committed_bundle_is_built_from_the_current_sources() {
    let built = std::fs::read_to_string(repo().join("web/dist/source.sha256")).expect("web/dist/source.sha256");
    assert_eq!(
        built.trim(),
        source_hash(),
        "web/dist is stale against web/src, web/*.json/ts/html or api/: run `npm ci && npm run build` in web/ and commit web/dist"
    );
}

#[tokio::test]
async fn the_server_serves_the_page_and_every_asset_it_names() {
    let server = TestServer::start().await;
    let res = server.client.get(server.url("/")).send().await.unwrap();
    assert_eq!(res.status(), 200);
    assert_eq!(res.headers()["content-type"], "text/html; charset=utf-8");
    assert!(res.headers()["content-security-policy"].to_str().unwrap().contains("default-src 'self'"));
    let html = res.text().await.unwrap();
    assert_eq!(html, std::fs::read_to_string(repo().join("web/dist/index.html")).unwrap());
    // Every script and stylesheet the page names is served, byte for byte the committed file,
    // with a long cache life (their names carry their content's hash), and 304 on its ETag.
    let names: Vec<&str> = html.split(['"', '\'']).filter(|s| s.starts_with("/assets/")).collect();
    assert!(names.iter().any(|n| n.ends_with(".js")) && names.iter().any(|n| n.ends_with(".css")), "{names:?}");
    for name in names {
        let res = server.client.get(server.url(name)).send().await.unwrap();
        assert_eq!(res.status(), 200, "{name}");
        assert!(res.headers()["cache-control"].to_str().unwrap().contains("immutable"));
        let etag = res.headers()["etag"].clone();
        let body = res.bytes().await.unwrap();
        assert_eq!(body.as_ref(), std::fs::read(repo().join("web/dist").join(&name[1..])).unwrap(), "{name}");
        let again = server.client.get(server.url(name)).header("if-none-match", etag).send().await.unwrap();
        assert_eq!(again.status(), 304, "{name}");
    }
    let missing = server.client.get(server.url("/assets/nothing.js")).send().await.unwrap();
    assert_eq!(missing.status(), 404);
    assert_eq!(missing.headers()["content-type"], "application/problem+json");
}
