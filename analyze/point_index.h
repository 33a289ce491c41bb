#pragma once

// Internal to analyze/: a k-d tree (nanoflann) over a subset of a point list, answering
// nearest, k-nearest and radius queries with indices into the original list, and a
// chunked parallel loop whose results do not depend on the thread count.

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <thread>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <nanoflann.hpp>

namespace hw::analyze {

class PointIndex {
 public:
  // Indexes points[subset[i]]. `points` must outlive the index.
  PointIndex(const std::vector<Eigen::Vector3d>& points, std::vector<int> subset)
      : subset_(std::move(subset)), adaptor_{&points, &subset_} {
    tree_ = std::make_unique<Tree>(3, adaptor_, nanoflann::KDTreeSingleIndexAdaptorParams(16));
    tree_->buildIndex();
  }
  PointIndex(const PointIndex&) = delete;
  PointIndex& operator=(const PointIndex&) = delete;

  bool Empty() const { return subset_.empty(); }

  // The nearest indexed point (index into `points`) and its squared distance, m²; -1 when
  // the index is empty.
  int Nearest(const Eigen::Vector3d& query, double* distance_sq) const {
    if (subset_.empty()) return -1;
    uint32_t i = 0;
    double d2 = 0;
    tree_->knnSearch(query.data(), 1, &i, &d2);
    *distance_sq = d2;
    return subset_[i];
  }

  // Up to k nearest indexed points, nearest first.
  void Nearest(const Eigen::Vector3d& query, int k, std::vector<int>* out) const {
    out->clear();
    if (subset_.empty() || k <= 0) return;
    std::vector<uint32_t> idx(static_cast<size_t>(k));
    std::vector<double> d2(static_cast<size_t>(k));
    const size_t n = tree_->knnSearch(query.data(), static_cast<size_t>(k), idx.data(), d2.data());
    for (size_t j = 0; j < n; ++j) out->push_back(subset_[idx[j]]);
  }

  // Every indexed point within radius_m (inclusive), in no particular order.
  void Within(const Eigen::Vector3d& query, double radius_m, std::vector<int>* out) const {
    out->clear();
    if (subset_.empty()) return;
    std::vector<std::pair<uint32_t, double>> found;
    tree_->radiusSearch(query.data(), radius_m * radius_m, found, nanoflann::SearchParams(32, 0, false));
    for (const auto& f : found) out->push_back(subset_[f.first]);
  }

 private:
  struct Adaptor {
    const std::vector<Eigen::Vector3d>* points;
    const std::vector<int>* subset;
    size_t kdtree_get_point_count() const { return subset->size(); }
    double kdtree_get_pt(size_t i, size_t dim) const {
      return (*points)[static_cast<size_t>((*subset)[i])][static_cast<Eigen::Index>(dim)];
    }
    template <class Box>
    bool kdtree_get_bbox(Box& /*box*/) const {
      return false;
    }
  };
  using Tree =
      nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, Adaptor>, Adaptor, 3, uint32_t>;

  std::vector<int> subset_;
  Adaptor adaptor_;
  std::unique_ptr<Tree> tree_;
};

// Calls fn(chunk) for every chunk in [0, chunks), on up to `threads` threads (0: one per
// hardware thread). Callers write per-chunk results and reduce them in chunk order, so the
// result is the same for any thread count.
inline void ParallelChunks(int chunks, int threads, const std::function<void(int)>& fn) {
  int n = threads > 0 ? threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  n = std::min(n, chunks);
  if (n <= 1) {
    for (int c = 0; c < chunks; ++c) fn(c);
    return;
  }
  std::atomic<int> next{0};
  auto worker = [&] {
    for (int c = next++; c < chunks; c = next++) fn(c);
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < n; ++t) pool.emplace_back(worker);
  worker();
  for (std::thread& t : pool) t.join();
}

}  // namespace hw::analyze
