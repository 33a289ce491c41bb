#include "reconstruct/row_bands.h"

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <system_error>
#include <vector>

namespace hw::reconstruct::internal {
namespace {

// One RunPieces call. Shared with the workers, which may still hold it after the call has
// returned (a worker that woke late): it then has no piece left, and never calls `band`.
struct Job {
  const std::function<void(int, int)>* band = nullptr;
  int num_items = 0, num_pieces = 0;
  int max_workers = 0;           // pool workers that may take part (num_threads − 1)
  std::atomic<int> next{0};      // the next piece to take
  std::atomic<int> joined{0};    // workers that have taken part
  std::mutex mutex;
  std::condition_variable all_done;
  int finished = 0;  // pieces finished (under mutex)

  int Begin(int piece) const {
    return static_cast<int>(static_cast<long long>(num_items) * piece / num_pieces);
  }
  // Takes and runs pieces until none is left.
  void Work() {
    int ran = 0;
    for (int p = next.fetch_add(1); p < num_pieces; p = next.fetch_add(1), ++ran) (*band)(Begin(p), Begin(p + 1));
    if (ran == 0) return;
    const std::lock_guard<std::mutex> lock(mutex);
    finished += ran;
    if (finished == num_pieces) all_done.notify_all();
  }
};

// Persistent workers, started on first use (as many as the largest call asked for, less
// the caller), blocked on a condition variable between calls: no spinning.
class Pool {
 public:
  static Pool& Get() {
    static Pool pool;
    return pool;
  }
  ~Pool() {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    for (std::thread& worker : workers_) worker.join();
  }

  // Runs the job with the pool's help; false (nothing done) when the pool is serving
  // another call.
  bool Run(const std::shared_ptr<Job>& job, int num_threads) {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      if (current_) return false;
      while (static_cast<int>(workers_.size()) < num_threads - 1 && can_start_) {
        try {
          workers_.emplace_back([this] { Serve(); });
        } catch (const std::system_error&) {
          can_start_ = false;  // no thread to be had: the caller does the work
        }
      }
      current_ = job;
      ++generation_;
    }
    wake_.notify_all();
    job->Work();
    {
      std::unique_lock<std::mutex> lock(job->mutex);
      job->all_done.wait(lock, [&] { return job->finished == job->num_pieces; });
    }
    const std::lock_guard<std::mutex> lock(mutex_);
    current_.reset();
    return true;
  }

 private:
  Pool() = default;

  void Serve() {
    std::uint64_t seen = 0;
    for (;;) {
      std::shared_ptr<Job> job;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [&] { return stop_ || (current_ && generation_ != seen); });
        if (stop_) return;
        seen = generation_;
        job = current_;
      }
      if (job->joined.fetch_add(1) < job->max_workers) job->Work();
    }
  }

  std::mutex mutex_;
  std::condition_variable wake_;
  std::shared_ptr<Job> current_;
  std::uint64_t generation_ = 0;
  bool stop_ = false, can_start_ = true;
  std::vector<std::thread> workers_;
};

}  // namespace

void RunPieces(int num_items, int num_pieces, int num_threads, const std::function<void(int, int)>& band) {
  auto job = std::make_shared<Job>();
  job->band = &band;
  job->num_items = num_items;
  job->num_pieces = num_pieces;
  job->max_workers = num_threads - 1;
  if (!Pool::Get().Run(job, num_threads)) band(0, num_items);
}

}  // namespace hw::reconstruct::internal
