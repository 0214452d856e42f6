//! The in-process ingest rig shared by `bench daemon --day` and `bench soak`: a temporary
//! database, the register map of a bench plant with `tags` tags, the daemon's writer task and
//! a read-only detector connection whose scans are written through the writer, as in the
//! daemon. Each frame is encoded into register blocks as a PLC would answer and
//! decoded exactly as the poll loop does, with no Modbus server in between, so the figures are
//! the store's, writer's and detector's at full speed. Benchmark plumbing only: no assertions.

use super::daemon::{bench_map, tempfile_dir, TempDir};
use crate::acquire::modbus::{decode_request, PollPlan};
use crate::acquire::register_map::encode_field;
use crate::config::DaemonConfig;
use crate::daemon;
use crate::detect::{self, DetectorConfig};
use crate::plantsim::PlantFrame;
use crate::store::{
    spawn_writer, writer_channel, ReadStore, StorageConfig, Store, StoreError, TagInfo, ViaWriter,
    WriteCmd, WriterHandle, WriterStats,
};
use anyhow::Context;
use std::path::PathBuf;
use tokio::task::JoinHandle;

/// See the module comment.
pub(super) struct IngestRig {
    _dir: TempDir,
    pub db_path: PathBuf,
    plan: PollPlan,
    blocks: Vec<Vec<u16>>,
    tx: Option<WriterHandle>,
    writer: Option<JoinHandle<Result<WriterStats, StoreError>>>,
    det_store: Option<ReadStore>,
    /// Samples handed to the writer.
    pub samples: u64,
    pub scans: u64,
    pub segments_closed: u64,
}

impl IngestRig {
    /// A fresh database `db_name` in a temporary directory, with `tags` tags.
    pub(super) fn new(tags: usize, cache_mib: u32, db_name: &str) -> anyhow::Result<IngestRig> {
        let dir = tempfile_dir()?;
        let storage = StorageConfig {
            path: dir.path().join(db_name),
            cache_mib,
            ..StorageConfig::default()
        };
        let map = bench_map(tags, "127.0.0.1:502");
        let mut store = Store::open_with(&storage.path, &storage.options())?;
        let tag_ids = map
            .fields()
            .map(|(_, f)| {
                store.ensure_tag(&TagInfo {
                    name: f.name.clone(),
                    unit: f.unit.clone(),
                    signal: f.signal,
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let plan = PollPlan::new(&map, &tag_ids).map_err(anyhow::Error::msg)?;
        let (tx, rx) = writer_channel(DaemonConfig::default().queue_capacity);
        let writer = spawn_writer(store, rx, storage.writer());
        let det_store = Store::open_readonly_with(
            &storage.path,
            &daemon::detector_store_options(&storage.options()),
        )?;
        let blocks = plan
            .requests
            .iter()
            .map(|r| vec![0u16; r.count as usize])
            .collect();
        Ok(IngestRig {
            _dir: dir,
            db_path: storage.path,
            plan,
            blocks,
            tx: Some(tx),
            writer: Some(writer),
            det_store: Some(det_store),
            samples: 0,
            scans: 0,
            segments_closed: 0,
        })
    }

    /// One poll: `frame` encoded into the register blocks (fields without a signal read
    /// `filler`), decoded at `t_ms` and handed to the writer.
    pub(super) async fn push(
        &mut self,
        frame: &PlantFrame,
        filler: f64,
        t_ms: i64,
    ) -> anyhow::Result<()> {
        for (req, block) in self.plan.requests.iter().zip(self.blocks.iter_mut()) {
            for (_, f) in &req.fields {
                let v = f.signal.map_or(filler, |s| frame.get(s));
                let at = (f.address - u32::from(req.start)) as usize;
                for (i, w) in encode_field(f, v).into_iter().enumerate() {
                    block[at + i] = w;
                }
            }
        }
        let mut batch = Vec::with_capacity(self.plan.tag_count());
        for (req, block) in self.plan.requests.iter().zip(&self.blocks) {
            decode_request(req, block, t_ms, &mut batch);
        }
        self.samples += batch.len() as u64;
        self.tx
            .as_ref()
            .context("writer closed")?
            .send(WriteCmd::Samples(batch))
            .await
            .context("writer stopped")
    }

    /// A handle on the rig's writer (None once closed), for the daemon's other tasks.
    pub(super) fn writer(&self) -> Option<WriterHandle> {
        self.tx.clone()
    }

    /// Flushes the writer, then runs one detector scan on the blocking pool (read-only, written
    /// through the writer).
    pub(super) async fn scan(&mut self) -> anyhow::Result<()> {
        let tx = self.tx.clone().context("writer closed")?;
        tx.flush()
            .await
            .context("writer stopped before the flush")?;
        let s = self.det_store.take().context("detector store")?;
        let (s, r) = tokio::task::spawn_blocking(move || {
            let mut db = ViaWriter {
                read: &s,
                writer: &tx,
            };
            let r = detect::scan(&mut db, &DetectorConfig::default());
            (s, r)
        })
        .await?;
        self.det_store = Some(s);
        let r = r?;
        self.scans += 1;
        self.segments_closed += r.segments_closed;
        Ok(())
    }

    /// Closes the writer's queue and waits for its last commit.
    pub(super) async fn close_writer(&mut self) -> anyhow::Result<()> {
        self.tx = None;
        if let Some(w) = self.writer.take() {
            w.await??;
        }
        Ok(())
    }

    /// Closes the detector's connection.
    pub(super) fn close_detector(&mut self) {
        self.det_store = None;
    }
}
