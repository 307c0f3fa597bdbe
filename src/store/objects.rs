//! Artifact bytes in an object store instead of the database: an S3-compatible bucket
//! (`s3://bucket/prefix`, credentials, region and endpoint from the usual `AWS_*` variables) or
//! a directory (`file:///path`), through the `object_store` crate.
//!
//! The database keeps each artifact's row (name, type, size, sha256) and the key of its object.
//! Every finish writes its objects under a key of its own (`{job}/{finish id}/{name}`), before
//! the transaction that records them: nothing is ever overwritten, so a reader of the old row
//! never sees new bytes, and a worker whose claim was fenced off leaves nothing behind — the
//! objects of a write the database refused, and those a new finish or a delete replaced, are
//! removed afterwards (best effort: an object left by a crash in between is garbage no row
//! points at, never a wrong artifact).

use std::ops::Range;
use std::sync::Arc;

use futures::TryStreamExt;
use object_store::path::Path;
use object_store::{ObjectStore, PutPayload, WriteMultipart};

use super::StoreError;
use crate::export::Artifact;

/// Artifacts larger than this are uploaded in parts of this size, so the upload never holds a
/// second whole copy.
const PART_BYTES: usize = 8 << 20;

pub struct ObjectArtifacts {
    store: Arc<dyn ObjectStore>,
    /// Where the objects live, for messages.
    location: String,
    /// The store's methods are blocking (called from worker threads and `spawn_blocking`); the
    /// object store's are async, and run here.
    runtime: Option<tokio::runtime::Runtime>,
}

impl std::fmt::Debug for ObjectArtifacts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ObjectArtifacts").field("location", &self.location).finish_non_exhaustive()
    }
}

impl Drop for ObjectArtifacts {
    fn drop(&mut self) {
        // A runtime dropped on an async thread would panic; this one needs no waiting for.
        if let Some(rt) = self.runtime.take() {
            rt.shutdown_background();
        }
    }
}

fn backend(location: &str) -> impl Fn(object_store::Error) -> StoreError + '_ {
    move |e| StoreError::Backend(format!("object store {location}: {e}"))
}

impl ObjectArtifacts {
    /// Open the object store `url` names: `s3://bucket[/prefix]` or `file:///directory`
    /// (created if missing).
    pub fn open(url: &str) -> Result<Self, StoreError> {
        let bad = |why: &str| StoreError::Backend(format!("artifact store {url:?}: {why}"));
        let store: Arc<dyn ObjectStore> = if let Some(rest) = url.strip_prefix("s3://") {
            let (bucket, prefix) = rest.split_once('/').unwrap_or((rest, ""));
            if bucket.is_empty() {
                return Err(bad("no bucket"));
            }
            let s3 = object_store::aws::AmazonS3Builder::from_env()
                .with_bucket_name(bucket)
                .build()
                .map_err(|e| bad(&e.to_string()))?;
            with_prefix(Arc::new(s3), prefix)
        } else if let Some(dir) = url.strip_prefix("file://") {
            if !dir.starts_with('/') {
                return Err(bad("a file:// location needs an absolute path"));
            }
            std::fs::create_dir_all(dir).map_err(|e| bad(&e.to_string()))?;
            let local = object_store::local::LocalFileSystem::new_with_prefix(dir).map_err(|e| bad(&e.to_string()))?;
            Arc::new(local)
        } else {
            return Err(bad("expected s3://bucket[/prefix] or file:///directory"));
        };
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .thread_name("landform-objects")
            .enable_all()
            .build()
            .map_err(|e| bad(&e.to_string()))?;
        Ok(Self { store, location: url.to_string(), runtime: Some(runtime) })
    }

    fn block_on<T>(&self, f: impl std::future::Future<Output = T>) -> T {
        self.runtime.as_ref().expect("the runtime lives until drop").block_on(f)
    }

    /// Write a finish's artifacts, each under a new key; the keys, in the artifacts' order.
    /// Objects written before a failure are removed again.
    pub(super) fn put_all(&self, job_id: &str, artifacts: &[Artifact]) -> Result<Placed<'_>, StoreError> {
        let finish = uuid::Uuid::now_v7().simple().to_string();
        let mut placed = Placed { objects: self, keys: Vec::with_capacity(artifacts.len()), kept: false };
        for a in artifacts {
            let key = format!("{job_id}/{finish}/{}", a.name);
            self.block_on(self.put(&key, &a.bytes))?;
            placed.keys.push(key);
        }
        Ok(placed)
    }

    async fn put(&self, key: &str, bytes: &[u8]) -> Result<(), StoreError> {
        let (path, err) = (Path::from(key), backend(&self.location));
        if bytes.len() <= PART_BYTES {
            self.store.put(&path, PutPayload::from(bytes.to_vec())).await.map_err(err)?;
            return Ok(());
        }
        let upload = self.store.put_multipart(&path).await.map_err(&err)?;
        let mut write = WriteMultipart::new_with_chunk_size(upload, PART_BYTES);
        for part in bytes.chunks(PART_BYTES) {
            write.wait_for_capacity(2).await.map_err(&err)?;
            write.write(part);
        }
        write.finish().await.map_err(err)?;
        Ok(())
    }

    /// Bytes `range` of the object at `key` (the caller clips the range to the artifact's
    /// size); `None` when the object is gone (its job was deleted or finished again meanwhile).
    pub(super) fn read(&self, key: &str, range: Range<u64>) -> Result<Option<Vec<u8>>, StoreError> {
        if range.is_empty() {
            return Ok(Some(Vec::new()));
        }
        let path = Path::from(key);
        match self.block_on(self.store.get_range(&path, range)) {
            Ok(bytes) => Ok(Some(bytes.to_vec())),
            Err(object_store::Error::NotFound { .. }) => Ok(None),
            Err(e) => Err(backend(&self.location)(e)),
        }
    }

    /// Remove objects no row points at any more. Failures are logged, not returned: the rows
    /// are already right, and a leftover object is only garbage.
    pub(super) fn remove(&self, keys: &[String]) {
        if keys.is_empty() {
            return;
        }
        let locations = futures::stream::iter(keys.iter().map(|k| Ok(Path::from(k.as_str()))));
        let removed = self
            .block_on(async { self.store.delete_stream(Box::pin(locations)).try_for_each(|_| async { Ok(()) }).await });
        match removed {
            Ok(()) | Err(object_store::Error::NotFound { .. }) => {}
            Err(e) => tracing::warn!(error = %e, location = %self.location, "could not remove replaced artifacts"),
        }
    }
}

fn with_prefix(store: Arc<dyn ObjectStore>, prefix: &str) -> Arc<dyn ObjectStore> {
    let prefix = prefix.trim_matches('/');
    if prefix.is_empty() {
        store
    } else {
        Arc::new(object_store::prefix::PrefixStore::new(store, prefix))
    }
}

/// Objects a finish wrote: removed again when dropped unless the rows that point at them were
/// committed (`keep`).
pub(super) struct Placed<'a> {
    objects: &'a ObjectArtifacts,
    pub keys: Vec<String>,
    kept: bool,
}

impl Placed<'_> {
    pub fn keep(mut self) {
        self.kept = true;
    }
}

impl Drop for Placed<'_> {
    fn drop(&mut self) {
        if !self.kept {
            self.objects.remove(&self.keys);
        }
    }
}

/// At most `len` bytes from `offset` of an artifact of `total` bytes kept at `key` (as
/// `ArtifactStore::read_artifact` reads them); `None` when the object is gone.
pub(super) fn object_range(
    objects: Option<&ObjectArtifacts>,
    key: &str,
    total: i64,
    offset: u64,
    len: usize,
) -> Result<Option<Vec<u8>>, StoreError> {
    let objects = objects.ok_or_else(|| {
        StoreError::Backend(format!(
            "artifact {key} is in an object store, and this process has none (--artifact-store)"
        ))
    })?;
    let total = total.max(0) as u64;
    let start = offset.min(total);
    let end = start.saturating_add(len as u64).min(total);
    let bytes = objects.read(key, start..end)?;
    if let Some(b) = &bytes {
        if b.len() as u64 != end - start {
            return Err(StoreError::Corrupt(format!("object {key}: {} bytes where {} were due", b.len(), end - start)));
        }
    }
    Ok(bytes)
}
