#pragma once

/// @file haptics/servo_loop.hpp
/// @brief ServoLoop: a haptic device coupled to a Simulation through a virtual coupling, at 1 kHz,
/// with a force clamp, a force ramp-in and a watchdog; lock-free snapshots for the render side.

#include <atomic>
#include <chrono>
#include <functional>
#include <limits>
#include <memory>
#include <thread>
#include <vector>

#include "fsm/collision/contact.hpp"
#include "fsm/detail/triple_buffer.hpp"
#include "fsm/haptics/haptic_device.hpp"
#include "fsm/simulation.hpp"

namespace fsm::haptics {

/// @brief How the loop runs and couples.
struct ServoOptions {
  /// Servo rate (Hz); the simulation steps at h = 1/rate.
  double rate{1000};
  /// How the device tick and the simulation step share threads:
  /// `lockstep`: one thread does both every period (deterministic: the same force curve in real
  /// time as in run_fast()); a watchdog thread watches it. `decoupled`: the device tick runs on
  /// its own (in the device's scheduler when it has one, else in a thread) and the simulation in
  /// another thread; the tick evaluates the virtual coupling against the latest proxy state, which
  /// is the local model that keeps the force smooth when a step is late.
  enum class Threading { lockstep, decoupled } threading{Threading::lockstep};

  /// Virtual coupling between the device tip and the instrument (the proxy): a spring (N/m) and
  /// a damper (N s/m). The device feels \f$k_c(x_p - x_d) + b_c(v_p - v_d)\f$; the proxy, of mass
  /// `proxy_mass` (kg), feels the opposite plus the tissue's contact force, integrated implicitly
  /// in the coupling. A stiffer coupling feels crisper and needs a device that can render it (the
  /// Touch: about 1 N/mm at most).
  double coupling_stiffness{400};
  double coupling_damping{4};
  double proxy_mass{0.02};

  /// Force clamp (N); 0 uses the device's limit. The smaller of this and the device's applies.
  double max_force{0};
  /// The force ramps in linearly over this time (s) after start.
  double ramp_time{0.25};
  /// The force goes to zero when the simulation has not completed a step for this long (s), or
  /// when a step diverges (the simulation rolls it back).
  double watchdog_timeout{1.5e-3};
  /// Decoupled: how long (s) the tick's local contact model may stand in for a simulation step
  /// that is late before the watchdog zeroes the force (the larger of this and
  /// watchdog_timeout applies). A step retried as half steps, or a busy second core, makes a
  /// step a millisecond or two late; the local model keeps the force that of the tissue as the
  /// last step left it. Lockstep ignores it (there the tick waits for the step).
  double local_model_timeout{0.02};
  /// After a trip, the force ramps in again once the simulation has stepped healthily for this
  /// long (s); 0 keeps it at zero until rearm().
  double recover_time{0.1};

  /// Device frame to simulation frame: x_sim = device_offset + device_scale * device_rotation *
  /// x_device (m). Forces are rotated back (not scaled).
  Vector3<double> device_offset{Vector3<double>::Zero()};
  Eigen::Quaterniond device_rotation{Eigen::Quaterniond::Identity()};
  double device_scale{1};

  /// The servo thread busy-waits for each deadline (true: it keeps a core, and the period is
  /// exact to a few us) or sleeps to 400 us before it and spins the rest (false: sleeps on a
  /// virtual machine overshoot by up to a millisecond now and then). The decoupled simulation
  /// thread always sleeps.
  bool spin{true};

  /// Real-time scheduling (Linux): 0 runs the loop's threads under the default scheduler; 2-98
  /// asks `SCHED_FIFO` at this priority for the servo thread and the watchdog, and one below for
  /// the decoupled simulation thread, so that other busy processes on the machine cannot
  /// deschedule them. It needs root, `CAP_SYS_NICE` or a real-time priority limit (`ulimit -r`,
  /// `rtprio` in limits.conf); where the system refuses, the loop runs under the default
  /// scheduler and stats().realtime says so. A real-time servo thread never spins a whole period
  /// (the kernel throttles a real-time thread that keeps a core 950 ms of every second): it
  /// sleeps to `realtime_spin` (s) before each deadline and spins the rest, and when it is a
  /// period or more behind it skips to the tick due now (counting the skipped ones as missed)
  /// rather than running ticks back to back. A thread the loop borrows (run_real_time's caller)
  /// gets its scheduling back when the run ends. Not with a simulation on more than one thread
  /// (its pool's helpers run at the default priority; fsm::Error).
  int realtime_priority{0};
  double realtime_spin{150e-6};

  /// Ticks whose timing is kept for stats() (allocated up front); later ticks are not recorded.
  std::size_t max_recorded_ticks{180000};

  /// Snapshots also carry the spheres' velocities (for export: an extra copy of |V| x 3 doubles
  /// per step, preallocated).
  bool snapshot_velocities{false};
};

/// @brief Timing and safety figures of a run (s unless named otherwise).
struct ServoStats {
  std::size_t ticks{0};             ///< device ticks run
  std::size_t steps{0};             ///< simulation steps run
  std::size_t missed_deadlines{0};  ///< ticks that started a full period or more late
  double period_p50{0}, period_p99{0}, period_max{0};  ///< time between tick starts
  double period_error_p99{0}, period_error_max{0};     ///< |period - 1/rate|
  double step_p50{0}, step_p99{0}, step_max{0};        ///< simulation step (contacts + step)
  std::size_t watchdog_trips{0};                       ///< times the watchdog zeroed the force
  std::size_t diverged_steps{0};                       ///< steps the simulation rolled back
  /// Integrator steps whose linear solve stopped at its iteration cap short of its tolerance
  /// (StepReport::unconverged_solves summed over the steps)
  std::size_t unconverged_solves{0};
  /// Sub-step levels run again because they gained energy an implicit step cannot make
  /// (StepReport::energy_gain_retries summed over the steps; DivergencePolicy::energy_gain_strain)
  std::size_t energy_gain_retries{0};
  /// The largest energy an accepted step ended with beyond its start energy plus the work done on
  /// it (J; StepReport::energy_gain); NaN when no step's energy was checked
  double largest_energy_gain{std::numeric_limits<double>::quiet_NaN()};
  double peak_force{0};  ///< largest commanded force magnitude (N)
  /// largest contact force on the instrument (N), over every simulation step (what
  /// ServoSnapshot::tissue_force carries)
  double peak_tissue_force{0};
  /// Every loop thread that asked for real-time scheduling (ServoOptions::realtime_priority) got
  /// it; false when none was asked for or the system refused.
  bool realtime{false};
};

/// @brief What the render side reads: the newest state the simulation published.
struct ServoSnapshot {
  double time{0};               ///< servo time of the step (s)
  Positions<double> positions;  ///< sphere centres (m), |V| x 3
  Positions<double>
      velocities;  ///< |V| x 3 (m/s) with ServoOptions::snapshot_velocities, else empty
  collision::Pose<double> instrument;                        ///< the proxy's pose
  Vector3<double> device_position{Vector3<double>::Zero()};  ///< device tip, simulation frame (m)
  Vector3<double> force{Vector3<double>::Zero()};         ///< last commanded force, sim frame (N)
  Vector3<double> tissue_force{Vector3<double>::Zero()};  ///< contact force on the instrument (N)
  double step_time{0};  ///< wall time of this step: contacts + simulation step (s)
  bool advanced{true};  ///< false: this step diverged and was rolled back
};

/// @brief What an instrument does besides pushing the tissue (cut it, grasp it): the servo loop
/// calls it inside every simulation step with the instrument's pose, and adds its wrench to what
/// the proxy and the device feel. Both calls run on the simulation's thread and must not
/// allocate, throw or wait on a lock (docs/haptics.md).
class InstrumentAction {
 public:
  virtual ~InstrumentAction() = default;
  /// After the contacts are computed and before the step: the instrument's pose and velocity
  /// (simulation frame, m/s) and the servo time (s). Cut here (Simulation::cut), or update a
  /// collision::Grasper.
  virtual void before_step(Simulation<double>& sim, const collision::Pose<double>& pose,
                           const Vector3<double>& velocity, double t) noexcept = 0;
  /// After the step: the force (N) the action puts on the instrument, with its stiffness and
  /// damping (the proxy takes them implicitly, as the contacts').
  [[nodiscard]] virtual collision::Wrench<double> wrench(
      const Simulation<double>& sim) const noexcept = 0;
};

/// @brief Couples a HapticDevice to a Simulation at the servo rate.
///
/// Each device tick: read the device at the nominal tick time, map it into the simulation frame,
/// evaluate the coupling force against the proxy, apply the safety chain (watchdog, ramp, clamp)
/// and command the force. Each simulation step: move the proxy under coupling and tissue forces,
/// pose the instrument on it, hand the contacts to the simulation's force model (implicit Euler
/// takes them into its solve), step, read the contacts' end-of-step wrench, and publish a
/// snapshot. Neither allocates nor throws; the device tick takes no lock.
///
/// The simulation, the contact solver and the device must outlive the loop and must not be touched
/// by others while it runs (read snapshots instead).
class ServoLoop {
 public:
  /// @param sim the simulation to step (its penalty contacts are replaced every step; its external
  /// forces are left to the caller)
  /// @param contacts the contact solver for sim's model
  /// @param instrument the instrument of `contacts` the device drives
  /// @param device the device
  ServoLoop(Simulation<double>& sim, collision::ContactSolver<double>& contacts, Index instrument,
            HapticDevice& device, const ServoOptions& options = {});
  ~ServoLoop();
  ServoLoop(const ServoLoop&) = delete;
  ServoLoop& operator=(const ServoLoop&) = delete;

  /// @brief Runs `seconds` of servo time as fast as possible in the calling thread (lockstep, no
  /// watchdog: there is no wall clock to miss). Starts and stops the device.
  void run_fast(double seconds);
  /// @brief Runs `seconds` in real time and returns when done (threads as options().threading).
  void run_real_time(double seconds);
  /// @brief Starts real-time running in the background; stop() ends it.
  void start();
  /// @brief Stops a background run, zeroes the force and stops the device. Never throws.
  void stop() noexcept;
  [[nodiscard]] bool running() const noexcept { return m_running.load(); }

  /// @brief True after the watchdog or a diverged step zeroed the force.
  [[nodiscard]] bool tripped() const noexcept { return m_tripped.load(); }
  /// @brief The device the loop drives.
  [[nodiscard]] HapticDevice& device() const noexcept { return m_device; }
  /// @brief Clears a trip now; the force ramps in again.
  void rearm() noexcept;

  /// @brief Copies the newest snapshot into `out` if there is one newer than the last read
  /// (render thread only; lock-free). Returns whether `out` changed.
  bool read_snapshot(ServoSnapshot& out);
  /// @brief Timing and safety figures so far (call when not running, or accept a racy read of
  /// the counters).
  [[nodiscard]] ServoStats stats() const;
  [[nodiscard]] const ServoOptions& options() const noexcept { return m_options; }
  /// @brief Duration (s) of each simulation step of the last run, in order (up to
  /// options().max_recorded_ticks; read when not running).
  [[nodiscard]] const std::vector<float>& step_times() const noexcept { return m_step_times; }

  /// @brief A function called inside every simulation step with the servo time (s): for tests
  /// (inject a stall) and for scripted loads. Set before running.
  void set_step_hook(std::function<void(double)> hook) { m_hook = std::move(hook); }
  /// @brief The instrument's action (a blade, a grasper), or nullptr; not owned, must outlive the
  /// runs. Set before running.
  void set_action(InstrumentAction* action) noexcept { m_action = action; }

 private:
  using Clock = std::chrono::steady_clock;
  struct DeviceSample {
    double time{0};
    Vector3<double> position{Vector3<double>::Zero()}, velocity{Vector3<double>::Zero()};
    Eigen::Quaterniond orientation{Eigen::Quaterniond::Identity()};
    Vector3<double> force{Vector3<double>::Zero()};  // commanded at this tick, simulation frame
  };
  struct ProxySample {
    Vector3<double> position{Vector3<double>::Zero()}, velocity{Vector3<double>::Zero()};
  };
  // The tissue's contact force on the instrument at the end of a step, linearised about the proxy
  // state the step used: f(x, v) = force - stiffness (x - position) - damping (v - velocity).
  struct TissueSample {
    Vector3<double> force{Vector3<double>::Zero()};
    Vector3<double> position{Vector3<double>::Zero()}, velocity{Vector3<double>::Zero()};
    Eigen::Matrix3d stiffness{Eigen::Matrix3d::Zero()}, damping{Eigen::Matrix3d::Zero()};
  };
  // The instrument's last wrench, linearised about the physics side's proxy state.
  [[nodiscard]] TissueSample tissue_sample() const noexcept;
  // One backward-Euler step of the proxy under the coupling to `d` and the linearised tissue.
  void advance_proxy(ProxySample& p, const DeviceSample& d,
                     const TissueSample& tissue) const noexcept;

  /// Resets the run's state; `local_model`: the tick advances the proxy (decoupled real time).
  void begin(bool local_model);
  void end() noexcept;
  void device_tick(double t) noexcept;
  void physics_step(double t) noexcept;
  /// The paced 1 kHz loop: device tick, then (lockstep, `with_step`) the simulation step.
  void servo_thread(double seconds, bool with_step) noexcept;
  /// No simulation step has completed for watchdog_timeout.
  [[nodiscard]] bool heartbeat_stale(Clock::time_point now) const noexcept;
  void physics_thread(double seconds) noexcept;
  void watchdog_thread() noexcept;
  void trip() noexcept;
  /// Waits for `deadline`: spinning (`spin`), sleeping to options().realtime_spin before it and
  /// spinning the rest (`realtime`), else sleeping to 400 us before it.
  void wait_until(Clock::time_point deadline, bool spin, bool realtime) const noexcept;
  /// Asks real-time scheduling at options().realtime_priority - `below` for the calling thread
  /// (when options().realtime_priority > 0) and counts the answer; returns whether it was granted.
  bool enter_realtime(int below) noexcept;
  [[nodiscard]] double now() const noexcept;

  Simulation<double>& m_sim;
  collision::ContactSolver<double>& m_contacts;
  Index m_instrument;
  HapticDevice& m_device;
  ServoOptions m_options;
  double m_period;
  double m_max_force{0};
  std::function<void(double)> m_hook;
  InstrumentAction* m_action{nullptr};
  collision::Wrench<double> m_action_wrench;  // the action's wrench at the end of the last step

  detail::TripleBuffer<DeviceSample> m_device_buffer;
  detail::TripleBuffer<ProxySample> m_proxy_buffer;
  detail::TripleBuffer<ServoSnapshot> m_snapshots;
  ProxySample m_proxy;  // physics side
  // Decoupled real-time runs: the tick advances its own proxy against the latest linearised
  // tissue (the local model) and hands it to the simulation thread.
  bool m_local_model{false};
  ProxySample m_tick_proxy;  // tick side
  detail::TripleBuffer<TissueSample> m_tissue_buffer;
  detail::TripleBuffer<ProxySample> m_tick_proxy_buffer;

  std::atomic<bool> m_running{false}, m_stop{false}, m_tripped{false};
  std::atomic<std::int64_t> m_heartbeat_ns{0};  // when the last step completed (ns since m_t0)
  Clock::time_point m_t0;
  std::atomic<double> m_rearm_time{0};
  std::vector<std::thread> m_threads;

  // Stats (each written by one thread).
  std::vector<float> m_periods, m_step_times;
  std::atomic<std::size_t> m_ticks{0}, m_steps{0}, m_missed{0}, m_trips{0}, m_diverged{0},
      m_unconverged{0}, m_gain_retries{0};
  // The largest StepReport::energy_gain of an accepted step; -infinity before the first checked
  // one.
  std::atomic<double> m_largest_gain{-std::numeric_limits<double>::infinity()};
  std::atomic<double> m_peak_tissue{0};  // the largest ServoSnapshot::tissue_force, every step
  std::atomic<std::size_t> m_healthy_steps{0};
  std::atomic<int> m_rt_asked{0}, m_rt_granted{0};
  std::atomic<double> m_peak{0};
  Clock::time_point m_last_tick_start;
};

}  // namespace fsm::haptics
