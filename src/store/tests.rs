use super::*;

fn temp_store() -> (tempfile::TempDir, Store) {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = Store::open(&dir.path().join("t.db")).expect("open");
    (dir, store)
}

#[test]
fn open_sets_wal_and_schema() {
    let (_d, store) = temp_store();
    let mode: String = store
        .conn()
        .query_row("PRAGMA journal_mode", [], |r| r.get(0))
        .expect("pragma");
    assert_eq!(mode, "wal");
    let v: i64 = store
        .conn()
        .query_row("PRAGMA user_version", [], |r| r.get(0))
        .expect("pragma");
    assert_eq!(v as usize, schema::latest_version());
    for view in [
        "v_startups",
        "v_health_trend",
        "v_latest_health",
        "v_gaps",
        "v_tag_latest",
        "v_samples",
    ] {
        store
            .conn()
            .prepare(&format!("SELECT * FROM {view}"))
            .unwrap_or_else(|e| panic!("{view}: {e}"));
    }
}

#[test]
fn insert_is_idempotent_and_tags_are_stable() {
    let (_d, mut store) = temp_store();
    let n1 = store
        .ensure_tag(&TagInfo::for_signal(Signal::N1))
        .expect("tag");
    let again = store
        .ensure_tag(&TagInfo::for_signal(Signal::N1))
        .expect("tag");
    assert_eq!(n1, again);
    let batch: Vec<Sample> = (0..100)
        .map(|i| Sample {
            tag: n1,
            t_ms: 1_000 * i,
            value: i as f64,
            quality: Quality::Good,
        })
        .collect();
    assert_eq!(store.insert_samples(&batch).expect("insert"), 100);
    assert_eq!(store.insert_samples(&batch).expect("insert"), 0);
    assert_eq!(store.insert_samples(&batch[50..]).expect("insert"), 0);
    assert_eq!(store.sample_count().expect("count"), 100);
    assert_eq!(
        store.tag_for_signal(Signal::N1).expect("q").map(|t| t.id),
        Some(n1)
    );
}

#[test]
fn gaps_are_idempotent() {
    let (_d, mut store) = temp_store();
    let g = Gap {
        start_ms: 10,
        end_ms: 5000,
        source: "modbus".into(),
        reason: "timeout".into(),
    };
    store.record_gap(&g).expect("gap");
    store.record_gap(&g).expect("gap");
    assert_eq!(store.gaps_between(0, 100).expect("gaps"), vec![g]);
    assert!(store.gaps_between(6000, 7000).expect("gaps").is_empty());
}

#[test]
fn readonly_refuses_missing_or_uninitialised_db() {
    let dir = tempfile::tempdir().expect("tempdir");
    assert!(Store::open_readonly(&dir.path().join("none.db")).is_err());
    let p = dir.path().join("x.db");
    rusqlite::Connection::open(&p).expect("create");
    assert!(matches!(
        Store::open_readonly(&p),
        Err(StoreError::NotInitialised { .. })
    ));
    drop(Store::open(&p).expect("init"));
    let ro = Store::open_readonly(&p).expect("ro");
    assert!(ro.conn().execute("DELETE FROM tags", []).is_err());
}

/// A store left with a hot rollback journal (a process killed while the file was still in
/// rollback mode, as while it is being created): a read-only open refuses it by name rather
/// than reading the half-written pages `immutable`; one writable open rolls it back.
#[test]
fn readonly_refuses_an_unfinished_write_and_a_writer_rolls_it_back() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("x.db");
    drop(Store::open(&p).expect("init"));
    let conn = rusqlite::Connection::open(&p).expect("open");
    let mode: String = conn
        .query_row("PRAGMA journal_mode=DELETE", [], |r| r.get(0))
        .expect("rollback mode");
    assert_eq!(mode, "delete");
    // A transaction large enough to spill into the file, caught mid-way by copying the file
    // and its journal: the copy is what a kill leaves.
    conn.execute_batch(
        "PRAGMA cache_size=1; BEGIN; CREATE TABLE junk(x BLOB);
         WITH RECURSIVE n(i) AS (SELECT 1 UNION ALL SELECT i + 1 FROM n WHERE i < 200)
         INSERT INTO junk SELECT randomblob(4000) FROM n;",
    )
    .expect("write");
    let killed = dir.path().join("killed.db");
    std::fs::copy(&p, &killed).expect("copy file");
    std::fs::copy(
        dir.path().join("x.db-journal"),
        dir.path().join("killed.db-journal"),
    )
    .expect("copy journal");
    conn.execute_batch("ROLLBACK").expect("rollback");
    drop(conn);

    match Store::open_readonly(&killed) {
        Err(e @ StoreError::UnfinishedWrite { .. }) => {
            assert!(e.to_string().contains("gtwatch store vacuum"), "{e}")
        }
        other => panic!("expected UnfinishedWrite, got {:?}", other.map(|_| ())),
    }
    let mut w = Store::open(&killed).expect("a writer rolls it back");
    let junk: i64 = w
        .conn_mut()
        .query_row(
            "SELECT COUNT(*) FROM sqlite_master WHERE name = 'junk'",
            [],
            |r| r.get(0),
        )
        .expect("schema");
    assert_eq!(junk, 0, "the unfinished transaction is rolled back");
    drop(w);
    assert!(Store::open_readonly(&killed).is_ok());
}

#[tokio::test]
async fn writer_batches_and_flushes_on_close() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("w.db");
    let mut store = Store::open(&path).expect("open");
    let tag = store
        .ensure_tag(&TagInfo::for_signal(Signal::Power))
        .expect("tag");
    let (tx, rx) = tokio::sync::mpsc::channel(16);
    let cfg = WriterConfig {
        batch_size: 250,
        flush_interval: Duration::from_secs(3600),
        ..WriterConfig::default()
    };
    let h = spawn_writer(store, rx, cfg);
    for k in 0..10 {
        let batch = (0..100)
            .map(|i| Sample {
                tag,
                t_ms: k * 100 + i,
                value: 1.0,
                quality: Quality::Good,
            })
            .collect();
        tx.send(WriteCmd::Samples(batch)).await.expect("send");
    }
    let (ack_tx, ack_rx) = tokio::sync::oneshot::channel();
    tx.send(WriteCmd::Flush(ack_tx)).await.expect("send");
    ack_rx.await.expect("ack");
    // Visible to another connection once acknowledged.
    let ro = Store::open_readonly(&path).expect("ro");
    assert_eq!(ro.sample_count().expect("count"), 1000);
    tx.send(WriteCmd::Gap(Gap {
        start_ms: 0,
        end_ms: 1,
        source: "test".into(),
        reason: "r".into(),
    }))
    .await
    .expect("send");
    tx.send(WriteCmd::Samples(vec![Sample {
        tag,
        t_ms: 0,
        value: 2.0,
        quality: Quality::Bad,
    }]))
    .await
    .expect("send");
    drop(tx);
    let stats = h.await.expect("join").expect("writer");
    assert_eq!(stats.samples_received, 1001);
    assert_eq!(stats.samples_inserted, 1000);
    assert_eq!(stats.samples_duplicate, 1);
    assert_eq!(stats.gaps, 1);
    assert_eq!(ro.gaps_between(0, 10).expect("gaps").len(), 1);
}

#[tokio::test]
async fn writer_flushes_on_interval() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("w.db");
    let mut store = Store::open(&path).expect("open");
    let tag = store
        .ensure_tag(&TagInfo::for_signal(Signal::N1))
        .expect("tag");
    let (tx, rx) = tokio::sync::mpsc::channel(16);
    let cfg = WriterConfig {
        batch_size: 1_000_000,
        flush_interval: Duration::from_millis(20),
        ..WriterConfig::default()
    };
    let h = spawn_writer(store, rx, cfg);
    tx.send(WriteCmd::Samples(vec![Sample {
        tag,
        t_ms: 5,
        value: 1.0,
        quality: Quality::Good,
    }]))
    .await
    .expect("send");
    let ro = Store::open_readonly(&path).expect("ro");
    let mut seen = 0;
    for _ in 0..200 {
        tokio::time::sleep(Duration::from_millis(10)).await;
        seen = ro.sample_count().expect("count");
        if seen == 1 {
            break;
        }
    }
    assert_eq!(seen, 1, "interval flush did not happen");
    drop(tx);
    let stats = h.await.expect("join").expect("writer");
    assert_eq!(stats.transactions, 1);
}

#[test]
fn read_store_never_creates_a_file_and_reads_beside_an_open_write_transaction() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("r.db");
    assert!(Store::open_readonly(&p).is_err(), "no database to read");
    assert!(!p.exists(), "a reader created the file");
    let mut w = Store::open(&p).expect("open");
    let tag = w
        .ensure_tag(&TagInfo {
            name: "n1_rpm".into(),
            unit: "rpm".into(),
            signal: None,
        })
        .expect("tag");
    let s = |t_ms| Sample {
        tag,
        t_ms,
        value: 1.0,
        quality: Quality::Good,
    };
    w.insert_samples(&[s(1), s(2)]).expect("insert");
    // The writer now holds the write lock with uncommitted rows.
    let tx = w
        .conn_mut()
        .transaction_with_behavior(rusqlite::TransactionBehavior::Immediate)
        .expect("begin");
    tx.execute(
        "INSERT INTO samples (tag_id, t_ms, value, quality) VALUES (?1, 3, 1.0, 0)",
        [tag],
    )
    .expect("uncommitted insert");
    let r = Store::open_readonly(&p).expect("reader opens while the writer holds the lock");
    assert_eq!(
        r.sample_count().expect("count"),
        2,
        "sees committed rows only"
    );
    tx.commit().expect("commit");
    assert_eq!(r.sample_count().expect("count"), 3);
}

fn samples(tag: i64, from: i64, n: i64) -> Vec<Sample> {
    (from..from + n)
        .map(|i| Sample {
            tag,
            t_ms: i * 1000,
            value: i as f64,
            quality: Quality::Good,
        })
        .collect()
}

/// Issue 12 #2: the disk fills (SQLITE_FULL via `PRAGMA max_page_count` on the writer's
/// connection, with the room taken by a filler table). The writer must stay alive, keep the
/// failed batches, and commit them once space is freed (the filler deleted by another
/// connection): no sample lost, none duplicated.
#[tokio::test]
async fn writer_survives_disk_full_and_recovers_without_loss() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("full.db");
    let mut store = Store::open(&path).expect("open");
    let tag = store
        .ensure_tag(&TagInfo::for_signal(Signal::N1))
        .expect("tag");
    store
        .conn()
        .execute_batch(
            "CREATE TABLE filler (b BLOB);
             WITH RECURSIVE c(i) AS (SELECT 1 UNION ALL SELECT i + 1 FROM c WHERE i < 200)
             INSERT INTO filler SELECT zeroblob(4000) FROM c;",
        )
        .expect("filler");
    // Some samples committed before the disk fills.
    store.insert_samples(&samples(tag, 0, 100)).expect("before");
    let pages: i64 = store
        .conn()
        .query_row("PRAGMA page_count", [], |r| r.get(0))
        .expect("page_count");
    let _: i64 = store
        .conn()
        .query_row(&format!("PRAGMA max_page_count = {pages}"), [], |r| {
            r.get(0)
        })
        .expect("max_page_count");
    let (tx, rx) = tokio::sync::mpsc::channel(64);
    let cfg = WriterConfig {
        batch_size: 500,
        flush_interval: Duration::from_millis(10),
        retry_initial: Duration::from_millis(20),
        ..WriterConfig::default()
    };
    let h = spawn_writer(store, rx, cfg);
    // 20 000 samples cannot fit in the pages left.
    for k in 0..40 {
        tx.send(WriteCmd::Samples(samples(tag, 100 + k * 500, 500)))
            .await
            .expect("writer alive while the disk is full");
    }
    let (ack_tx, mut ack_rx) = tokio::sync::oneshot::channel();
    tx.send(WriteCmd::Flush(ack_tx)).await.expect("send");
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert!(
        ack_rx.try_recv().is_err(),
        "a flush must not be acknowledged while its data is not committed"
    );
    assert!(!h.is_finished(), "the writer died on SQLITE_FULL");
    // Free space: another connection drops the filler.
    {
        let other = rusqlite::Connection::open(&path).expect("other");
        other.busy_timeout(Duration::from_secs(5)).expect("busy");
        other
            .execute_batch("DELETE FROM filler;")
            .expect("free space");
    }
    tokio::time::timeout(Duration::from_secs(10), ack_rx)
        .await
        .expect("recovered within 10 s")
        .expect("ack");
    drop(tx);
    let stats = h.await.expect("join").expect("writer");
    assert!(stats.write_errors >= 1, "{stats:?}");
    assert_eq!(stats.write_error_episodes, 1, "{stats:?}");
    assert_eq!(stats.samples_dropped, 0);
    assert_eq!(stats.samples_inserted, 20_000);
    assert_eq!(stats.samples_duplicate, 0);
    let ro = Store::open_readonly(&path).expect("ro");
    assert_eq!(ro.sample_count().expect("count"), 20_100);
    let distinct: i64 = ro
        .conn()
        .query_row(
            "SELECT COUNT(DISTINCT t_ms) FROM samples WHERE tag_id = ?1",
            [tag],
            |r| r.get(0),
        )
        .expect("distinct");
    assert_eq!(distinct, 20_100);
    assert_eq!(ro.integrity_check().expect("check"), "ok");
}

/// When the buffer overflows during an episode the excess is dropped and its span recorded
/// as a gap once writing resumes.
#[tokio::test]
async fn writer_overflow_records_a_gap() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("over.db");
    let mut store = Store::open(&path).expect("open");
    let tag = store
        .ensure_tag(&TagInfo::for_signal(Signal::N1))
        .expect("tag");
    store
        .conn()
        .execute_batch(
            "CREATE TABLE filler (b BLOB);
             WITH RECURSIVE c(i) AS (SELECT 1 UNION ALL SELECT i + 1 FROM c WHERE i < 100)
             INSERT INTO filler SELECT zeroblob(4000) FROM c;",
        )
        .expect("filler");
    let pages: i64 = store
        .conn()
        .query_row("PRAGMA page_count", [], |r| r.get(0))
        .expect("page_count");
    let _: i64 = store
        .conn()
        .query_row(&format!("PRAGMA max_page_count = {pages}"), [], |r| {
            r.get(0)
        })
        .expect("max_page_count");
    let (tx, rx) = tokio::sync::mpsc::channel(64);
    let cfg = WriterConfig {
        batch_size: 1000,
        flush_interval: Duration::from_millis(5),
        retry_initial: Duration::from_millis(20),
        max_buffered: 3000,
        ..WriterConfig::default()
    };
    let h = spawn_writer(store, rx, cfg);
    for k in 0..10 {
        tx.send(WriteCmd::Samples(samples(tag, k * 1000, 1000)))
            .await
            .expect("send");
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    {
        let other = rusqlite::Connection::open(&path).expect("other");
        other.busy_timeout(Duration::from_secs(5)).expect("busy");
        other
            .execute_batch("DELETE FROM filler;")
            .expect("free space");
    }
    let (ack_tx, ack_rx) = tokio::sync::oneshot::channel();
    tx.send(WriteCmd::Flush(ack_tx)).await.expect("send");
    tokio::time::timeout(Duration::from_secs(10), ack_rx)
        .await
        .expect("recovered")
        .expect("ack");
    drop(tx);
    let stats = h.await.expect("join").expect("writer");
    assert_eq!(
        stats.samples_inserted + stats.samples_dropped,
        10_000,
        "{stats:?}"
    );
    assert!(stats.samples_dropped > 0, "{stats:?}");
    let ro = Store::open_readonly(&path).expect("ro");
    let gaps = ro.gaps_between(0, i64::MAX).expect("gaps");
    // One gap per retry that found new drops; together they cover every dropped sample.
    assert!(!gaps.is_empty());
    for g in &gaps {
        assert_eq!(g.source, "writer");
        assert!(g.reason.starts_with("writer_buffer_full"), "{gaps:?}");
    }
    let stored: Vec<i64> = {
        let mut st = ro
            .conn()
            .prepare("SELECT t_ms FROM samples WHERE tag_id = ?1")
            .expect("prep");
        let rows = st.query_map([tag], |r| r.get(0)).expect("q");
        rows.collect::<Result<_, _>>().expect("rows")
    };
    for k in 0..10_000_i64 {
        let t = k * 1000;
        let covered = gaps.iter().any(|g| g.start_ms <= t && t <= g.end_ms);
        assert!(
            stored.binary_search(&t).is_ok() || covered,
            "sample {t} lost without a gap"
        );
    }
}

/// `storage.max_db_mib` caps the file: past it inserts fail with SQLITE_FULL (what the writer
/// survives as a full disk), and the file stays within the cap.
#[test]
fn max_db_mib_caps_the_database_with_sqlite_full() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("cap.db");
    let opts = StorageConfig {
        path: path.clone(),
        max_db_mib: 1,
        ..StorageConfig::default()
    }
    .options();
    let mut store = Store::open_with(&path, &opts).expect("open");
    let tag = store
        .ensure_tag(&TagInfo::for_signal(Signal::N1))
        .expect("tag");
    let mut full = None;
    for k in 0..200 {
        if let Err(e) = store.insert_samples(&samples(tag, k * 1000, 1000)) {
            full = Some(e);
            break;
        }
    }
    match full {
        Some(StoreError::Sql(rusqlite::Error::SqliteFailure(e, _))) => {
            assert_eq!(e.code, rusqlite::ErrorCode::DiskFull)
        }
        other => panic!("expected SQLITE_FULL within 200 000 samples, got {other:?}"),
    }
    let (pages, size): (i64, i64) = store
        .conn()
        .query_row(
            "SELECT (SELECT page_count FROM pragma_page_count), (SELECT page_size FROM pragma_page_size)",
            [],
            |r| Ok((r.get(0)?, r.get(1)?)),
        )
        .expect("size");
    assert!(pages * size <= 1024 * 1024, "{pages} pages of {size}");
    assert!(pages * size > 900 * 1024, "{pages} pages of {size}");
    assert_eq!(
        StorageConfig {
            max_db_mib: u32::MAX,
            ..StorageConfig::default()
        }
        .validate()
        .len(),
        1
    );
}
