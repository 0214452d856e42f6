//! The Modbus TCP server of the plant simulator: a task steps a [`PlantModel`] (on a timer or in
//! lock-step with the poller) and encodes every frame into a register image per the register
//! map (the inverse of the daemon's decoder), publishing the true phase in `phase_truth` and
//! the plant clock in `plant_time_ms` when the map has those fields.
//!
//! Answers reads only (function codes 3 and 4); anything else gets "illegal function". Must
//! never be pointed at a real control network as if it were the plant.

use super::{PlantFrame, PlantModel};
use crate::acquire::register_map::{
    encode_field, ModbusConfig, RegisterKind, MAX_REGISTERS_PER_REQUEST, PHASE_TRUTH_FIELD,
    PLANT_TIME_FIELD,
};
use std::collections::HashMap;
use std::future::Future;
use std::io;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex, RwLock};
use std::time::Duration;
use tokio::net::TcpListener;
use tokio::sync::watch;
use tokio_modbus::prelude::{ExceptionCode, Request, Response, SlaveRequest};
use tokio_modbus::server::tcp::{accept_tcp_connection, Server};

/// Register images of the simulated slaves, keyed by (slave id, table).
#[derive(Debug, Default)]
struct Image {
    tables: HashMap<(u8, RegisterKind), Vec<u16>>,
    /// Frames published so far.
    frames: u64,
}

/// Writes one frame into the register image per the map (the inverse of the decoder).
/// `epoch_ms` is the plant clock at model time 0 (for the `plant_time_ms` field).
fn publish(image: &mut Image, map: &ModbusConfig, frame: &PlantFrame, epoch_ms: i64) {
    for req in &map.requests {
        let table = image
            .tables
            .entry((req.slave_id, req.register))
            .or_insert_with(|| vec![0; 65536]);
        for f in &req.fields {
            let value = match f.signal {
                Some(s) => frame.get(s),
                None if f.name == PHASE_TRUTH_FIELD => f64::from(frame.phase.code()),
                None if f.name == PLANT_TIME_FIELD => {
                    // Whole milliseconds: f64 holds them exactly up to 2^53 ms (year 287 396).
                    epoch_ms as f64 + (frame.t_s * 1000.0).round()
                }
                None => 0.0,
            };
            for (i, w) in encode_field(f, value).into_iter().enumerate() {
                if let Some(slot) = table.get_mut(f.address as usize + i) {
                    *slot = w;
                }
            }
        }
    }
    image.frames += 1;
}

/// The plant side of the simulator: the model, stepped either by a timer or by reads.
struct Stepper {
    model: Box<dyn PlantModel>,
    map: ModbusConfig,
    image: Arc<RwLock<Image>>,
    frames_tx: watch::Sender<u64>,
    produced: u64,
    max_frames: Option<u64>,
    /// Plant clock at model time 0, Unix epoch ms.
    epoch_ms: i64,
}

impl Stepper {
    /// Advances up to `n` frames and publishes the last one.
    fn advance(&mut self, n: u64) {
        let mut last = None;
        for _ in 0..n {
            if self.max_frames.is_some_and(|m| self.produced >= m) {
                break;
            }
            self.produced += 1;
            last = Some(self.model.step());
        }
        if let Some(frame) = last {
            if let Ok(mut img) = self.image.write() {
                publish(&mut img, &self.map, &frame, self.epoch_ms);
            }
            let _ = self.frames_tx.send(self.produced);
        }
    }
}

/// In lock-step mode, a read of this block advances the plant one frame first.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct StepTrigger {
    slave: u8,
    kind: RegisterKind,
    start: u16,
}

/// The Modbus service: answers reads from the shared image.
struct SimService {
    image: Arc<RwLock<Image>>,
    lockstep: Option<(StepTrigger, Arc<Mutex<Stepper>>)>,
}

impl tokio_modbus::server::Service for SimService {
    type Request = SlaveRequest<'static>;
    type Response = Response;
    type Exception = ExceptionCode;
    type Future = std::future::Ready<Result<Response, ExceptionCode>>;

    fn call(&self, req: Self::Request) -> Self::Future {
        let (kind, addr, cnt) = match req.request {
            Request::ReadHoldingRegisters(a, c) => (RegisterKind::Holding, a, c),
            Request::ReadInputRegisters(a, c) => (RegisterKind::Input, a, c),
            _ => return std::future::ready(Err(ExceptionCode::IllegalFunction)),
        };
        if let Some((trigger, stepper)) = &self.lockstep {
            let this = StepTrigger {
                slave: req.slave,
                kind,
                start: addr,
            };
            if this == *trigger {
                if let Ok(mut st) = stepper.lock() {
                    st.advance(1);
                }
            }
        }
        std::future::ready(read_image(&self.image, req.slave, kind, addr, cnt))
    }
}

fn read_image(
    image: &RwLock<Image>,
    slave: u8,
    kind: RegisterKind,
    addr: u16,
    cnt: u16,
) -> Result<Response, ExceptionCode> {
    if cnt == 0 || u32::from(cnt) > MAX_REGISTERS_PER_REQUEST {
        return Err(ExceptionCode::IllegalDataValue);
    }
    let img = image
        .read()
        .map_err(|_| ExceptionCode::ServerDeviceFailure)?;
    let table = img
        .tables
        .get(&(slave, kind))
        .ok_or(ExceptionCode::GatewayTargetDevice)?;
    let words = table
        .get(addr as usize..addr as usize + cnt as usize)
        .ok_or(ExceptionCode::IllegalDataAddress)?
        .to_vec();
    Ok(match kind {
        RegisterKind::Holding => Response::ReadHoldingRegisters(words),
        RegisterKind::Input => Response::ReadInputRegisters(words),
    })
}

/// How fast the simulated plant runs.
#[derive(Debug, Clone, PartialEq)]
pub struct SimOptions {
    /// Plant frames per model period of wall time (1 = real time). Frames are produced on a
    /// wall tick of `tick`; each tick advances as many frames as have accrued.
    pub speedup: f64,
    /// Wall-clock update interval; default the model period (clamped to ≥ 1 ms).
    pub tick: Option<Duration>,
    /// Instead of a timer, advance one frame whenever a client reads the map's first request
    /// block (`speedup` and `tick` are then unused). The plant then moves in lock-step with a
    /// single poller, so every poll sees exactly the next frame: tests compare detection with
    /// the truth sample by sample, which two free-running clocks (plant tick, poll tick) would
    /// blur with repeated and skipped frames under CPU load.
    pub lockstep: bool,
}

impl Default for SimOptions {
    fn default() -> Self {
        SimOptions {
            speedup: 1.0,
            tick: None,
            lockstep: false,
        }
    }
}

/// A running plant simulator. Dropping the handle does not stop it; call [`PlantSimHandle::stop`].
#[derive(Debug)]
pub struct PlantSimHandle {
    pub local_addr: SocketAddr,
    stop_tx: watch::Sender<bool>,
    frames: watch::Receiver<u64>,
    task: tokio::task::JoinHandle<io::Result<()>>,
}

impl PlantSimHandle {
    /// Frames published so far.
    pub fn frames(&self) -> u64 {
        *self.frames.borrow()
    }

    /// Waits until at least `n` frames have been published.
    pub async fn wait_frames(&mut self, n: u64) {
        let _ = self.frames.wait_for(|&f| f >= n).await;
    }

    /// Stops the server (closing the listener and every connection) and the plant.
    pub async fn stop(self) -> io::Result<()> {
        let _ = self.stop_tx.send(true);
        match self.task.await {
            Ok(r) => r,
            Err(e) => Err(io::Error::other(e)),
        }
    }
}

/// Starts the plant simulator on `listener`: a task steps `model` and publishes frames into the
/// register image; the Modbus server answers reads from it. `max_frames` stops the plant (the
/// last frame stays published) after that many frames, e.g. at the end of a test schedule.
pub fn spawn_plant_sim(
    listener: TcpListener,
    map: ModbusConfig,
    model: Box<dyn PlantModel>,
    opts: SimOptions,
    max_frames: Option<u64>,
) -> io::Result<PlantSimHandle> {
    let local_addr = listener.local_addr()?;
    let image = Arc::new(RwLock::new(Image::default()));
    let (stop_tx, mut stop_rx) = watch::channel(false);
    let (frames_tx, frames_rx) = watch::channel(0u64);
    let period = model.period_s().max(1e-6);
    let tick = opts
        .tick
        .unwrap_or_else(|| Duration::from_secs_f64(period))
        .max(Duration::from_millis(1));
    let frames_per_tick = opts.speedup.max(0.0) * tick.as_secs_f64() / period;
    let trigger = map.requests.first().and_then(|r| {
        Some(StepTrigger {
            slave: r.slave_id,
            kind: r.register,
            start: u16::try_from(r.start_address).ok()?,
        })
    });
    let epoch_ms = model.epoch_ms().unwrap_or_else(|| {
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_millis() as i64)
    });
    let stepper = Arc::new(Mutex::new(Stepper {
        model,
        map,
        image: Arc::clone(&image),
        frames_tx,
        produced: 0,
        max_frames,
        epoch_ms,
    }));
    // Publish the first frame before accepting connections, so a client never reads zeros.
    stepper
        .lock()
        .map_err(|_| io::Error::other("plant lock"))?
        .advance(1);
    let lockstep = match (opts.lockstep, trigger) {
        (true, Some(t)) => Some((t, Arc::clone(&stepper))),
        (true, None) => return Err(io::Error::other("lock-step plant-sim needs a request")),
        (false, _) => None,
    };
    let timed = !opts.lockstep;
    let mut stop_plant = stop_rx.clone();
    let plant = async move {
        if !timed {
            return;
        }
        let mut interval = tokio::time::interval(tick);
        interval.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        interval.tick().await;
        let mut owed = 0.0;
        loop {
            tokio::select! {
                _ = interval.tick() => {}
                _ = stop_plant.changed() => break,
            }
            owed += frames_per_tick;
            let whole = owed.floor();
            owed -= whole;
            if whole >= 1.0 {
                if let Ok(mut st) = stepper.lock() {
                    st.advance(whole as u64);
                }
            }
        }
    };
    let server_image = image;
    let task = tokio::spawn(async move {
        let plant_task = tokio::spawn(plant);
        let server = Server::new(listener);
        let new_service = move |_addr: SocketAddr| {
            Ok(Some(SimService {
                image: Arc::clone(&server_image),
                lockstep: lockstep.clone(),
            }))
        };
        let on_connected = |stream, addr| {
            let new_service = new_service.clone();
            async move { accept_tcp_connection(stream, addr, new_service) }
        };
        let on_error = |err: io::Error| tracing::debug!("plant-sim connection: {err}");
        let stopped = async move {
            let _ = stop_rx.wait_for(|&s| s).await;
        };
        let r = server.serve_until(&on_connected, on_error, stopped).await;
        plant_task.abort();
        r.map(|_| ())
    });
    Ok(PlantSimHandle {
        local_addr,
        stop_tx,
        frames: frames_rx,
        task,
    })
}

/// Runs the plant simulator until `shutdown` completes (the `plant-sim` command).
pub async fn run_plant_sim(
    listen: SocketAddr,
    map: ModbusConfig,
    model: Box<dyn PlantModel>,
    opts: SimOptions,
    shutdown: impl Future<Output = ()>,
) -> io::Result<()> {
    let listener = TcpListener::bind(listen).await?;
    let handle = spawn_plant_sim(listener, map, model, opts, None)?;
    tracing::info!(addr = %handle.local_addr, "plant-sim serving");
    shutdown.await;
    handle.stop().await
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plantsim::{ScriptLevels, ScriptStep, ScriptTiming, ScriptedPlant};
    use crate::signals::Signal;

    fn quick_plant(schedule: &[ScriptStep]) -> ScriptedPlant {
        ScriptedPlant::new(
            schedule,
            &ScriptTiming::compressed(5.0),
            ScriptLevels::default(),
            0.5,
            false,
        )
    }

    #[tokio::test]
    async fn server_serves_the_frame_and_refuses_writes() {
        use crate::acquire::register_map::{
            decode_field, ByteOrder, DataType, FieldSpec, RequestSpec,
        };
        use tokio_modbus::prelude::*;
        let f = |name: &str, address, ty, order, signal| FieldSpec {
            name: String::from(name),
            address,
            data_type: ty,
            byte_order: order,
            scale: 1.0,
            offset: 0.0,
            unit: String::new(),
            signal,
            min: None,
            max: None,
        };
        let map = ModbusConfig {
            endpoint: "127.0.0.1:0".into(),
            requests: vec![RequestSpec {
                slave_id: 1,
                register: RegisterKind::Input,
                start_address: 100,
                count: None,
                fields: vec![
                    f("n1", 100, DataType::F32, ByteOrder::CDAB, Some(Signal::N1)),
                    f("p1", 102, DataType::F64, ByteOrder::DCBA, Some(Signal::P1)),
                    f(PHASE_TRUTH_FIELD, 106, DataType::U16, ByteOrder::ABCD, None),
                ],
            }],
        };
        let plant = quick_plant(&[ScriptStep::Start]);
        let expect = plant.frame_at(0.5);
        let listener = TcpListener::bind("127.0.0.1:0").await.expect("bind");
        let h = spawn_plant_sim(
            listener,
            map.clone(),
            Box::new(plant),
            SimOptions::default(),
            Some(1),
        )
        .expect("spawn");
        let mut ctx = tcp::connect_slave(h.local_addr, Slave(1))
            .await
            .expect("connect");
        let words = ctx
            .read_input_registers(100, 7)
            .await
            .expect("io")
            .expect("no exception");
        let req = &map.requests[0];
        let n1 = decode_field(&req.fields[0], 100, &words).expect("n1");
        assert_eq!(n1.value, f64::from(expect.get(Signal::N1) as f32));
        let p1 = decode_field(&req.fields[1], 100, &words).expect("p1");
        assert_eq!(p1.value, 101.325);
        let ph = decode_field(&req.fields[2], 100, &words).expect("phase");
        assert_eq!(ph.value, f64::from(expect.phase.code()));
        // Writes and unknown tables are refused.
        let w = ctx.write_single_register(100, 1).await.expect("io");
        assert_eq!(w, Err(ExceptionCode::IllegalFunction));
        let r = ctx.read_holding_registers(100, 1).await.expect("io");
        assert_eq!(r, Err(ExceptionCode::GatewayTargetDevice));
        let r = ctx.read_input_registers(65530, 10).await.expect("io");
        assert_eq!(r, Err(ExceptionCode::IllegalDataAddress));
        drop(ctx);
        h.stop().await.expect("stop");
    }
}
