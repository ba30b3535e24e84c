// ServoLoop: device tick, proxy and simulation step, safety chain, timing.

#include "fsm/haptics/servo_loop.hpp"

#include <algorithm>
#include <cmath>

#include "fsm/error.hpp"

#if defined(__linux__)
#include <pthread.h>
#include <sched.h>
#include <sys/prctl.h>
#endif

namespace fsm::haptics {

namespace {

// A servo thread gets the smallest timer slack, so that its sleeps wake on time.
void make_servo_thread() noexcept {
#if defined(__linux__)
  prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
#endif
}

// The calling thread's scheduling policy and priority, put back when the guard ends: a loop that
// borrows its caller's thread (run_real_time) leaves it as it found it.
class SchedulingGuard {
 public:
  SchedulingGuard() noexcept {
#if defined(__linux__)
    m_saved = pthread_getschedparam(pthread_self(), &m_policy, &m_param) == 0;
#endif
  }
  ~SchedulingGuard() {
#if defined(__linux__)
    if (m_saved) pthread_setschedparam(pthread_self(), m_policy, &m_param);
#endif
  }
  SchedulingGuard(const SchedulingGuard&) = delete;
  SchedulingGuard& operator=(const SchedulingGuard&) = delete;

 private:
#if defined(__linux__)
  bool m_saved{false};
  int m_policy{0};
  sched_param m_param{};
#endif
};

double percentile(std::vector<float> v, double q) {
  if (v.empty()) return 0;
  const std::size_t k = std::min(v.size() - 1, std::size_t(q * double(v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(k), v.end());
  return double(v[k]);
}

void atomic_max(std::atomic<double>& a, double value) noexcept {
  double old = a.load(std::memory_order_relaxed);
  while (value > old && !a.compare_exchange_weak(old, value, std::memory_order_relaxed)) {
  }
}

}  // namespace

ServoLoop::ServoLoop(Simulation<double>& sim, collision::ContactSolver<double>& contacts,
                     Index instrument, HapticDevice& device, const ServoOptions& options)
    : m_sim(sim),
      m_contacts(contacts),
      m_instrument(instrument),
      m_device(device),
      m_options(options),
      m_period(1.0 / options.rate),
      m_snapshots([&] {
        ServoSnapshot s;
        s.positions = sim.model().positions();
        if (options.snapshot_velocities) s.velocities = sim.model().velocities();
        return s;
      }()) {
  const auto& o = m_options;
  auto positive = [](double x) { return std::isfinite(x) && x > 0; };
  if (!positive(o.rate) || !positive(o.proxy_mass) || !(o.coupling_stiffness >= 0) ||
      !(o.coupling_damping >= 0) || !std::isfinite(o.coupling_stiffness) ||
      !std::isfinite(o.coupling_damping) || !(o.max_force >= 0) || !(o.ramp_time >= 0) ||
      !positive(o.watchdog_timeout) || !positive(o.device_scale) || !o.device_offset.allFinite() ||
      !(o.device_rotation.norm() > 0))
    throw Error("", "servo loop options",
                "rate, proxy_mass, watchdog_timeout and device_scale must be positive and finite; "
                "gains, max_force and ramp_time non-negative; the rotation non-zero");
  if (o.watchdog_timeout <= m_period)
    throw Error("", "servo loop options", "watchdog_timeout must exceed one servo period");
  if (!(o.local_model_timeout >= 0) || !std::isfinite(o.local_model_timeout))
    throw Error("", "servo loop options", "local_model_timeout must be finite and non-negative");
  if (o.realtime_priority != 0 && (o.realtime_priority < 2 || o.realtime_priority > 98))
    throw Error(
        "", "servo loop options",
        "realtime_priority must be 0 (off) or 2 to 98, got " + std::to_string(o.realtime_priority));
  if (!(o.realtime_spin >= 0) || !(o.realtime_spin <= m_period))
    throw Error("", "servo loop options", "realtime_spin must be between 0 and one servo period");
  if (o.realtime_priority > 0 && sim.forces().options().threads > 1)
    throw Error("", "servo loop options",
                "realtime_priority with a simulation on " +
                    std::to_string(sim.forces().options().threads) +
                    " threads: the worker pool's helpers run at the default priority, and a "
                    "real-time step would spin waiting for them; use one thread");
  if (instrument < 0 || instrument >= contacts.num_instruments())
    throw Error("", "servo loop", "instrument " + std::to_string(instrument) + " does not exist");
  m_options.device_rotation.normalize();
  m_periods.reserve(o.max_recorded_ticks);
  m_step_times.reserve(o.max_recorded_ticks);
}

ServoLoop::~ServoLoop() {
  stop();
}

double ServoLoop::now() const noexcept {
  return std::chrono::duration<double>(Clock::now() - m_t0).count();
}

void ServoLoop::wait_until(Clock::time_point deadline, bool spin, bool realtime) const noexcept {
  // Sleeping overshoots by 0.3-1.3 ms at p99-p99.9 on a virtual machine under the default
  // scheduler (measured), so the servo thread spins to the deadline when asked; otherwise it
  // sleeps to within 400 us and spins. A real-time thread wakes at once (it preempts every
  // default-scheduler thread) and must not spin whole periods (the kernel would throttle it).
  const auto margin = realtime ? std::chrono::duration_cast<Clock::duration>(
                                     std::chrono::duration<double>(m_options.realtime_spin))
                               : Clock::duration(std::chrono::microseconds(400));
  if ((realtime || !spin) && Clock::now() + margin < deadline)
    std::this_thread::sleep_until(deadline - margin);
  while (Clock::now() < deadline) {
  }
}

bool ServoLoop::enter_realtime(int below) noexcept {
  if (m_options.realtime_priority <= 0) return false;
  m_rt_asked.fetch_add(1, std::memory_order_relaxed);
  bool granted = false;
#if defined(__linux__)
  sched_param p{};
  p.sched_priority = m_options.realtime_priority - below;
  granted = pthread_setschedparam(pthread_self(), SCHED_FIFO, &p) == 0;
#else
  (void)below;
#endif
  if (granted) m_rt_granted.fetch_add(1, std::memory_order_relaxed);
  return granted;
}

void ServoLoop::begin(bool local_model) {
  if (m_running.exchange(true)) throw Error("", "servo loop", "already running");
  try {
    m_device.start();
  } catch (...) {
    m_running = false;
    throw;
  }
  const DeviceLimits lim = m_device.limits();
  m_max_force =
      m_options.max_force > 0 ? std::min(m_options.max_force, lim.max_force) : lim.max_force;
  m_local_model = local_model;
  m_action_wrench = collision::Wrench<double>{};
  m_stop = false;
  m_tripped = false;
  m_rearm_time = 0;
  m_periods.clear();
  m_step_times.clear();
  m_ticks = m_steps = m_missed = m_trips = m_diverged = m_unconverged = m_gain_retries = 0;
  m_largest_gain = -std::numeric_limits<double>::infinity();
  m_peak_tissue = 0;
  m_healthy_steps = 0;
  m_rt_asked = 0;
  m_rt_granted = 0;
  m_peak = 0;
  // The proxy starts at the device.
  const DeviceState s = m_device.read(0.0);
  DeviceSample& d = m_device_buffer.back();
  d.force.setZero();
  d.time = 0;
  d.position =
      m_options.device_offset + m_options.device_scale * (m_options.device_rotation * s.position);
  d.velocity.setZero();
  d.orientation = m_options.device_rotation * s.orientation;
  m_device_buffer.publish();
  m_proxy.position = d.position;
  m_proxy.velocity.setZero();
  m_proxy_buffer.back() = m_proxy;
  m_proxy_buffer.publish();
  m_tick_proxy = m_proxy;
  m_tick_proxy_buffer.back() = m_proxy;
  m_tick_proxy_buffer.publish();
  TissueSample& ts = m_tissue_buffer.back();
  ts = TissueSample{};
  ts.position = m_proxy.position;
  m_tissue_buffer.publish();
  m_t0 = Clock::now();
  m_last_tick_start = m_t0;
  m_heartbeat_ns = 0;
}

void ServoLoop::end() noexcept {
  m_stop = true;
  if (m_device.has_scheduler()) m_device.stop_scheduler();
  for (auto& t : m_threads)
    if (t.joinable()) t.join();
  m_threads.clear();
  m_device.apply_force(Vector3<double>::Zero());
  m_device.stop();
  m_running = false;
}

void ServoLoop::trip() noexcept {
  m_healthy_steps.store(0, std::memory_order_relaxed);
  if (!m_tripped.exchange(true)) {
    m_device.apply_force(Vector3<double>::Zero());
    ++m_trips;
  }
}

void ServoLoop::rearm() noexcept {
  m_rearm_time = m_running ? now() : 0.0;
  m_healthy_steps = 0;
  m_tripped = false;
}

void ServoLoop::device_tick(double t) noexcept {
  const DeviceState s = m_device.read(t);
  const ServoOptions& o = m_options;
  // Recovery: after recover_time of healthy steps since a trip, ramp in again.
  if (m_tripped.load(std::memory_order_acquire) && o.recover_time > 0 &&
      double(m_healthy_steps.load(std::memory_order_relaxed)) * m_period >= o.recover_time) {
    m_rearm_time.store(t, std::memory_order_relaxed);
    m_tripped.store(false, std::memory_order_release);
  }
  DeviceSample& d = m_device_buffer.back();
  d.time = t;
  d.position = o.device_offset + o.device_scale * (o.device_rotation * s.position);
  d.velocity = o.device_scale * (o.device_rotation * s.linear_velocity);
  d.orientation = o.device_rotation * s.orientation;
  const DeviceSample sample = d;

  if (!m_local_model) m_proxy_buffer.update();  // lockstep: the step just advanced it
  const ProxySample& p = m_local_model ? m_tick_proxy : m_proxy_buffer.front();
  Vector3<double> f = o.coupling_stiffness * (p.position - sample.position) +
                      o.coupling_damping * (p.velocity - sample.velocity);
  // Safety chain: a tripped loop commands zero; the force ramps in after start and after rearm();
  // the clamp is the smaller of ours and the device's.
  const double since = t - m_rearm_time.load(std::memory_order_relaxed);
  const double ramp = o.ramp_time > 0 ? std::clamp(since / o.ramp_time, 0.0, 1.0) : 1.0;
  // Decoupled, the tick then advances the proxy itself against the latest linearised tissue (as
  // the step does in lockstep, so with no contact the two give the same force), and the force
  // stays that of the tissue, to first order, when a step is late.
  if (m_local_model) {
    m_tissue_buffer.update();
    advance_proxy(m_tick_proxy, sample, m_tissue_buffer.front());
    m_tick_proxy_buffer.back() = m_tick_proxy;
    m_tick_proxy_buffer.publish();
  }
  if (!f.allFinite()) f.setZero();
  f *= ramp;
  const double n = f.norm();
  if (n > m_max_force) f *= m_max_force / n;
  if (m_tripped.load(std::memory_order_acquire)) f.setZero();
  const Vector3<double> commanded = m_device.apply_force(o.device_rotation.conjugate() * f);
  // The sample goes to the simulation side with the force it produced (for the snapshot).
  d.force = o.device_rotation * commanded;
  m_device_buffer.publish();
  atomic_max(m_peak, commanded.norm());
  ++m_ticks;
}

ServoLoop::TissueSample ServoLoop::tissue_sample() const noexcept {
  const auto& w = m_contacts.wrench(m_instrument);
  TissueSample t;
  t.force = w.force;
  t.stiffness = w.stiffness;
  t.damping = w.damping;
  t.force += m_action_wrench.force;
  t.stiffness += m_action_wrench.stiffness;
  t.damping += m_action_wrench.damping;
  t.position = m_proxy.position;
  t.velocity = m_proxy.velocity;
  return t;
}

void ServoLoop::advance_proxy(ProxySample& p, const DeviceSample& d,
                              const TissueSample& tissue) const noexcept {
  // m dv/dt = k (x_d - x) + b (v_d - v) + f_tissue, backward Euler in the coupling and in the
  // tissue's contact force, linearised as f_tissue(x + h v', v') = f_w - K (x + h v' - x_w) -
  // C (v' - v_w) (K, C: the wrench's contact stiffness and damping; the contacts are far stiffer
  // than the coupling, so an explicit tissue force would make the proxy ring):
  // (m + h (b + C) + h^2 (k + K)) v' = m v + h (k (x_d - x) + b v_d + f_w - K (x - x_w) + C v_w).
  const ServoOptions& o = m_options;
  const double h = m_period;
  const double k = o.coupling_stiffness, b = o.coupling_damping, m = o.proxy_mass;
  const Eigen::Matrix3d A = (m + h * b + h * h * k) * Eigen::Matrix3d::Identity() +
                            h * tissue.damping + h * h * tissue.stiffness;
  const Vector3<double> rhs =
      m * p.velocity +
      h * (k * (d.position - p.position) + b * d.velocity + tissue.force -
           tissue.stiffness * (p.position - tissue.position) + tissue.damping * tissue.velocity);
  // A is symmetric positive definite (m > 0, K and C positive semi-definite).
  Vector3<double> v = A.llt().solve(rhs);
  // The local model (decoupled: the same linearisation for many ticks) is one-sided: where it
  // would pull the proxy back into the tissue (a contact only pushes), the proxy moves free.
  if (m_local_model && tissue.force.squaredNorm() > 0) {
    const Vector3<double> f_end = tissue.force -
                                  tissue.stiffness * (p.position + h * v - tissue.position) -
                                  tissue.damping * (v - tissue.velocity);
    if (f_end.dot(tissue.force) < 0)
      v = (m * p.velocity + h * (k * (d.position - p.position) + b * d.velocity)) /
          (m + h * b + h * h * k);
  }
  if (!v.allFinite()) v.setZero();
  p.velocity = v;
  p.position += h * v;
}

void ServoLoop::physics_step(double t) noexcept {
  const auto start = Clock::now();
  if (m_hook) m_hook(t);
  m_device_buffer.update();
  const DeviceSample& d = m_device_buffer.front();
  auto& ins = m_contacts.instrument(m_instrument);
  if (m_local_model) {
    // Decoupled: the tick advanced the proxy; take its newest state.
    m_tick_proxy_buffer.update();
    m_proxy = m_tick_proxy_buffer.front();
  } else {
    // Lockstep: the tissue linearised about the last step's end, which is where the proxy is.
    advance_proxy(m_proxy, d, tissue_sample());
  }
  ins.pose.position = m_proxy.position;
  ins.pose.orientation = d.orientation;
  ins.linear_velocity = m_proxy.velocity;
  ins.angular_velocity.setZero();

  // The contacts at the proxy's new pose go into the step (implicitly with implicit Euler); the
  // wrench the proxy feels next tick is their force at the end of the step.
  m_contacts.compute(m_sim.model(), m_sim.forces());
  if (m_action != nullptr) m_action->before_step(m_sim, ins.pose, m_proxy.velocity, t);
  const StepReport report = m_sim.step(m_period);
  m_contacts.collect(m_sim.forces());
  if (report.unconverged_solves > 0)
    m_unconverged.fetch_add(std::size_t(report.unconverged_solves), std::memory_order_relaxed);
  if (report.energy_gain_retries > 0)
    m_gain_retries.fetch_add(std::size_t(report.energy_gain_retries), std::memory_order_relaxed);
  if (report.advanced() && std::isfinite(report.energy_gain))
    atomic_max(m_largest_gain, report.energy_gain);
  if (m_action != nullptr) m_action_wrench = m_action->wrench(m_sim);  // once per step
  if (!report.advanced()) {
    ++m_diverged;
    trip();
  } else {
    m_healthy_steps.fetch_add(1, std::memory_order_relaxed);
  }
  if (m_local_model) {
    m_tissue_buffer.back() = tissue_sample();
    m_tissue_buffer.publish();
  } else {
    m_proxy_buffer.back() = m_proxy;
    m_proxy_buffer.publish();
  }

  ServoSnapshot& s = m_snapshots.back();
  s.time = t;
  s.positions = m_sim.model().positions();  // same size: no allocation
  if (m_options.snapshot_velocities) s.velocities = m_sim.model().velocities();
  s.instrument = ins.pose;
  s.device_position = d.position;
  s.force = d.force;
  s.tissue_force = m_contacts.wrench(m_instrument).force;
  s.tissue_force += m_action_wrench.force;
  atomic_max(m_peak_tissue, s.tissue_force.norm());
  s.step_time = std::chrono::duration<double>(Clock::now() - start).count();
  s.advanced = report.advanced();
  m_snapshots.publish();

  const auto end = Clock::now();
  m_heartbeat_ns.store(std::chrono::duration_cast<std::chrono::nanoseconds>(end - m_t0).count(),
                       std::memory_order_release);
  if (m_step_times.size() < m_step_times.capacity())
    m_step_times.push_back(std::chrono::duration<float>(end - start).count());
  ++m_steps;
}

namespace {
// A run's length, checked before anything starts: finite, non-negative, and not so long that
// its tick count overflows (a trillion ticks is 30 years at 1 kHz).
void check_seconds(double seconds, double rate) {
  if (!(seconds >= 0) || !std::isfinite(seconds) || seconds * rate > 1e12)
    throw Error("", "servo loop",
                "seconds must be finite, non-negative and at most 1e12 ticks long, got " +
                    std::to_string(seconds));
}
}  // namespace

void ServoLoop::run_fast(double seconds) {
  check_seconds(seconds, m_options.rate);
  begin(false);
  const auto ticks = std::int64_t(std::llround(seconds * m_options.rate));
  for (std::int64_t k = 0; k < ticks; ++k) {
    const double t = double(k) * m_period;
    device_tick(t);
    physics_step(t);
  }
  end();
}

bool ServoLoop::heartbeat_stale(Clock::time_point now) const noexcept {
  // Before the first step completes the heartbeat is the start time.
  const auto beat = m_t0 + std::chrono::nanoseconds(m_heartbeat_ns.load(std::memory_order_acquire));
  // Decoupled, the local contact model stands in for a late step for local_model_timeout.
  const double timeout = m_local_model
                             ? std::max(m_options.watchdog_timeout, m_options.local_model_timeout)
                             : m_options.watchdog_timeout;
  return now - beat > std::chrono::duration<double>(timeout);
}

void ServoLoop::servo_thread(double seconds, bool with_step) noexcept {
  make_servo_thread();
  const SchedulingGuard guard;
  const bool realtime = enter_realtime(0);
  const auto period =
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(m_period));
  for (std::int64_t k = 0; !m_stop.load(std::memory_order_relaxed); ++k) {
    if (seconds > 0 && double(k) * m_period >= seconds) break;
    const auto deadline = m_t0 + k * period;
    wait_until(deadline, m_options.spin, realtime);
    const auto start = Clock::now();
    if (k > 0 && m_periods.size() < m_periods.capacity())
      m_periods.push_back(std::chrono::duration<float>(start - m_last_tick_start).count());
    if (start - deadline >= period) {
      ++m_missed;
      // A real-time thread never runs ticks back to back to catch up (it would hold its core
      // until the kernel throttles it): it skips to the tick due now, the skipped ones missed.
      if (realtime) {
        const std::int64_t due = (start - m_t0) / period;
        if (due > k) {
          m_missed += std::size_t(due - k - 1);
          k = due;
        }
      }
    }
    const double t = double(k) * m_period;
    if (seconds > 0 && t >= seconds) break;
    m_last_tick_start = start;
    // Decoupled, the tick is its own watchdog; in lockstep the watchdog thread is.
    if (!with_step && k > 0 && heartbeat_stale(start)) trip();
    device_tick(t);
    if (with_step) physics_step(t);
  }
  if (!with_step) m_stop = true;  // the simulation thread follows the tick's end
}

void ServoLoop::physics_thread(double seconds) noexcept {
  make_servo_thread();
  const SchedulingGuard guard;
  const bool realtime = enter_realtime(1);
  const auto period =
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(m_period));
  for (std::int64_t k = 0; !m_stop.load(std::memory_order_relaxed); ++k) {
    const double t = double(k) * m_period;
    if (seconds > 0 && t >= seconds) break;
    // Half a period after the tick that feeds it.
    wait_until(m_t0 + k * period + period / 2, false, realtime);
    if (realtime) {  // behind by a period or more: skip to the step due now (never back to back)
      const std::int64_t due = (Clock::now() - m_t0 - period / 2) / period;
      if (due > k) {
        k = due;
        if (seconds > 0 && double(k) * m_period >= seconds) break;
      }
    }
    physics_step(double(k) * m_period);
  }
}

void ServoLoop::watchdog_thread() noexcept {
  const SchedulingGuard guard;
  enter_realtime(0);
  while (!m_stop.load(std::memory_order_relaxed)) {
    std::this_thread::sleep_for(std::chrono::microseconds(250));
    if (heartbeat_stale(Clock::now())) trip();
  }
}

void ServoLoop::start() {
  begin(m_options.threading == ServoOptions::Threading::decoupled);
  try {
    if (m_options.threading == ServoOptions::Threading::lockstep) {
      m_threads.emplace_back([this] { servo_thread(0, true); });
      m_threads.emplace_back([this] { watchdog_thread(); });
    } else {
      m_threads.emplace_back([this] { physics_thread(0); });
      if (m_device.has_scheduler()) {
        auto k = std::make_shared<std::int64_t>(0);
        m_device.run_scheduler([this, k] {
          if (m_stop.load(std::memory_order_relaxed)) return false;
          if (*k > 0 && heartbeat_stale(Clock::now())) trip();
          device_tick(double((*k)++) * m_period);
          return true;
        });
      } else {
        m_threads.emplace_back([this] { servo_thread(0, false); });
      }
    }
  } catch (...) {
    end();
    throw;
  }
}

void ServoLoop::run_real_time(double seconds) {
  check_seconds(seconds, m_options.rate);
  begin(m_options.threading == ServoOptions::Threading::decoupled);
  try {
    if (m_options.threading == ServoOptions::Threading::lockstep) {
      std::thread watchdog([this] { watchdog_thread(); });
      servo_thread(seconds, true);
      m_stop = true;
      watchdog.join();
    } else {
      std::thread physics([this, seconds] { physics_thread(seconds); });
      servo_thread(seconds, false);
      m_stop = true;
      physics.join();
    }
  } catch (...) {
    end();
    throw;
  }
  end();
}

void ServoLoop::stop() noexcept {
  if (!m_running.load()) return;
  end();
}

bool ServoLoop::read_snapshot(ServoSnapshot& out) {
  if (!m_snapshots.update()) return false;
  out = m_snapshots.front();
  return true;
}

ServoStats ServoLoop::stats() const {
  ServoStats s;
  s.ticks = m_ticks;
  s.steps = m_steps;
  s.missed_deadlines = m_missed;
  s.watchdog_trips = m_trips;
  s.diverged_steps = m_diverged;
  s.unconverged_solves = m_unconverged;
  s.energy_gain_retries = m_gain_retries;
  const double gain = m_largest_gain.load(std::memory_order_relaxed);
  s.largest_energy_gain = std::isfinite(gain) ? gain : std::numeric_limits<double>::quiet_NaN();
  s.peak_tissue_force = m_peak_tissue;
  s.peak_force = m_peak;
  s.realtime = m_rt_asked.load() > 0 && m_rt_granted.load() == m_rt_asked.load();
  s.period_p50 = percentile(m_periods, 0.5);
  s.period_p99 = percentile(m_periods, 0.99);
  s.period_max =
      m_periods.empty() ? 0 : double(*std::max_element(m_periods.begin(), m_periods.end()));
  std::vector<float> err(m_periods.size());
  for (std::size_t i = 0; i < err.size(); ++i) err[i] = std::abs(m_periods[i] - float(m_period));
  s.period_error_p99 = percentile(err, 0.99);
  s.period_error_max = err.empty() ? 0 : double(*std::max_element(err.begin(), err.end()));
  s.step_p50 = percentile(m_step_times, 0.5);
  s.step_p99 = percentile(m_step_times, 0.99);
  s.step_max = m_step_times.empty()
                   ? 0
                   : double(*std::max_element(m_step_times.begin(), m_step_times.end()));
  return s;
}

}  // namespace fsm::haptics
