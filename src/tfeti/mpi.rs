//! [`Comm`] over MPI (the `mpi` feature): `MPI_Allgatherv`, `MPI_Allreduce` of
//! integers, `MPI_Bcast` and immediate sends and receives on `MPI_COMM_WORLD`, each timed so that a run can
//! say how much of its wall time went into communication.

use super::comm::{Comm, Op, Stats};
use super::lock;
use mpi::collective::SystemOperation;
use mpi::datatype::PartitionMut;
use mpi::environment::{Threading, Universe};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use mpi::Count;
use std::sync::Mutex;
use std::time::Instant;

/// Whether this process was started by an MPI launcher (`mpirun`, `srun`):
/// only then does `cso` initialize MPI, so that the feature build still runs
/// as a plain program.
pub fn launched() -> bool {
    [
        "OMPI_COMM_WORLD_SIZE",
        "PMI_SIZE",
        "PMIX_RANK",
        "MPI_LOCALNRANKS",
    ]
    .iter()
    .any(|v| std::env::var_os(v).is_some())
}

/// `MPI_COMM_WORLD` with the cost of its collectives.
pub struct Mpi {
    stats: Mutex<Stats>,
}

impl Mpi {
    /// Initializes MPI. Collectives come from one thread at a time (the
    /// thread that runs the solve), which `Serialized` allows. Keep the
    /// universe until the end of `main`: dropping it finalizes MPI.
    pub fn init() -> Result<(Mpi, Universe), String> {
        let (universe, threading) = mpi::initialize_with_threading(Threading::Serialized)
            .ok_or_else(|| "MPI was initialized twice".to_string())?;
        if threading < Threading::Serialized {
            return Err(format!(
                "the MPI library gives thread support {threading:?}, cso needs Serialized"
            ));
        }
        Ok((
            Mpi {
                stats: Mutex::new(Stats::default()),
            },
            universe,
        ))
    }

    /// `MPI_COMM_WORLD` (a handle, made per call: the handle type is not `Send`).
    fn world(&self) -> SimpleCommunicator {
        SimpleCommunicator::world()
    }

    /// A collective, timed and counted.
    fn timed<T>(&self, bytes: usize, f: impl FnOnce() -> T) -> T {
        self.counted(1, 0, bytes, f)
    }

    /// `f`, timed, counted as `calls` collectives and `messages` messages.
    fn counted<T>(&self, calls: u64, messages: u64, bytes: usize, f: impl FnOnce() -> T) -> T {
        let t = Instant::now();
        let out = f();
        let dt = t.elapsed().as_secs_f64();
        let mut s = lock(&self.stats);
        s.calls += calls;
        s.messages += messages;
        s.seconds += dt;
        s.bytes += bytes as u64;
        out
    }
}

fn layout(counts: &[usize]) -> (Vec<Count>, Vec<Count>, usize) {
    let c: Vec<Count> = counts.iter().map(|&n| n as Count).collect();
    let mut d = Vec::with_capacity(c.len());
    let mut at: Count = 0;
    for &n in &c {
        d.push(at);
        at += n;
    }
    (c, d, counts.iter().sum())
}

impl Comm for Mpi {
    fn rank(&self) -> usize {
        self.world().rank() as usize
    }

    fn size(&self) -> usize {
        self.world().size() as usize
    }

    fn all_gather(&self, local: &[f64], counts: &[usize]) -> Vec<f64> {
        let (c, d, total) = layout(counts);
        let mut out = vec![0.0; total];
        self.timed(8 * total, || {
            let mut part = PartitionMut::new(&mut out[..], c, d);
            self.world().all_gather_varcount_into(local, &mut part);
        });
        out
    }

    fn all_gather_u64(&self, local: &[u64], counts: &[usize]) -> Vec<u64> {
        let (c, d, total) = layout(counts);
        let mut out = vec![0u64; total];
        self.timed(8 * total, || {
            let mut part = PartitionMut::new(&mut out[..], c, d);
            self.world().all_gather_varcount_into(local, &mut part);
        });
        out
    }

    fn all_reduce_u64(&self, x: &mut [u64], op: Op) {
        let send = x.to_vec();
        let op = match op {
            Op::Sum => SystemOperation::sum(),
            Op::Min => SystemOperation::min(),
            Op::Max => SystemOperation::max(),
        };
        self.timed(8 * x.len(), || {
            self.world().all_reduce_into(&send[..], x, op);
        });
    }

    fn broadcast(&self, root: usize, bytes: &mut Vec<u8>) {
        let world = self.world();
        let root = world.process_at_rank(root as i32);
        let mut len = [bytes.len() as u64];
        self.timed(8, || root.broadcast_into(&mut len[..]));
        bytes.resize(len[0] as usize, 0);
        // An empty buffer is not broadcast (MPI refuses its null pointer);
        // every rank knows the length, so all skip it alike.
        if !bytes.is_empty() {
            self.timed(bytes.len(), || root.broadcast_into(&mut bytes[..]));
        }
    }

    fn exchange(&self, sends: &[(usize, Vec<f64>)], receives: &[(usize, usize)]) -> Vec<Vec<f64>> {
        let world = self.world();
        let mut out: Vec<Vec<f64>> = receives.iter().map(|&(_, n)| vec![0.0; n]).collect();
        let bytes = 8 * receives.iter().map(|r| r.1).sum::<usize>();
        self.counted(0, receives.len() as u64, bytes, || {
            mpi::request::scope(|scope| {
                let recv: Vec<_> = out
                    .iter_mut()
                    .zip(receives)
                    .map(|(buf, &(from, _))| {
                        world
                            .process_at_rank(from as i32)
                            .immediate_receive_into(scope, &mut buf[..])
                    })
                    .collect();
                let send: Vec<_> = sends
                    .iter()
                    .map(|(to, v)| {
                        world
                            .process_at_rank(*to as i32)
                            .immediate_send(scope, &v[..])
                    })
                    .collect();
                for r in recv {
                    r.wait();
                }
                for r in send {
                    r.wait();
                }
            });
        });
        out
    }

    fn stats(&self) -> Stats {
        *lock(&self.stats)
    }
}
