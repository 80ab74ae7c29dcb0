// The ranks of a bake (ranks.h): one process, farm shards, and MPI, the one file that calls
// MPI (built with it when CMake finds MPI and PRT_MPI is on: PRT_HAVE_MPI).
#include "prt/bake/ranks.h"

#include <algorithm>
#include <chrono>
#include <climits>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <thread>

#if PRT_HAVE_MPI
// The C API only (Open MPI's and MPICH's deprecated C++ bindings would need their library).
#define OMPI_SKIP_MPICXX 1
#define MPICH_SKIP_MPICXX 1
#include <mpi.h>
#endif

namespace prt::bake {

namespace {

Ranks gSingle;
Ranks* gRanks = &gSingle;

class ShardRanks final : public Ranks {
 public:
  ShardRanks(int index, int count) : index_(index), count_(count) {}
  int rank() const override { return index_; }
  int size() const override { return count_; }

 private:
  int index_, count_;
};

}  // namespace

std::vector<std::string> Ranks::gather(std::string mine, bool) {
  std::vector<std::string> all;
  all.push_back(std::move(mine));
  return all;
}

Ranks& ranks() { return *gRanks; }

RanksScope::RanksScope(Ranks* r) : previous_(gRanks) { gRanks = r ? r : &gSingle; }
RanksScope::~RanksScope() { gRanks = previous_; }

std::unique_ptr<Ranks> shardRanks(int index, int count) {
  PRT_CHECK_GT(count, 0);
  PRT_CHECK_GE(index, 0);
  PRT_CHECK_LT(index, count);
  return std::make_unique<ShardRanks>(index, count);
}

int launcherRank() {
  // Open MPI's mpirun; PMI (MPICH's hydra, Slurm's srun --mpi=pmi2). One rank is no spread.
  struct Pair {
    const char *rank, *size;
  };
  for (const Pair& p : {Pair{"OMPI_COMM_WORLD_RANK", "OMPI_COMM_WORLD_SIZE"}, Pair{"PMI_RANK", "PMI_SIZE"}}) {
    const char* r = std::getenv(p.rank);
    const char* s = std::getenv(p.size);
    if (r && s) return std::atoi(s) > 1 ? std::atoi(r) : -1;
  }
  return -1;
}

#if PRT_HAVE_MPI

namespace {

void check(int rc, const char* what) {
  if (rc != MPI_SUCCESS) throw Error(cat("MPI: ", what, " failed (error ", rc, ")"));
}

// Waits for a nonblocking collective. Arrival: polling with short sleeps, so that a rank that
// finished its share first leaves the core to the ranks still computing (Open MPI's blocking
// collectives spin), which matters where ranks share cores; sleeps grow from 50 µs to 2 ms.
// Transfer (every rank is known to be in the exchange already): polling without sleeping, as a
// nonblocking collective moves on only inside MPI calls: a large message goes in fragments,
// each a few calls, and 2 ms naps between them made the direct pass's 1 MB exchange on one
// machine take 90 ms instead of about 2.
enum class Wait { Arrival, Transfer };

void await(MPI_Request& request, const char* what, Wait wait = Wait::Arrival) {
  int done = 0;
  auto nap = std::chrono::microseconds(50);
  for (;;) {
    check(MPI_Test(&request, &done, MPI_STATUS_IGNORE), what);
    if (done) return;
    if (wait == Wait::Transfer) continue;
    std::this_thread::sleep_for(nap);
    nap = std::min(nap * 2, std::chrono::microseconds(2000));
  }
}

// Open MPI's default point-to-point layer tries the fabric ones first (UCX, libfabric): about
// 0.2 s of MPI_Init per rank on a machine without such a fabric (docs/scale.md). When every rank
// runs on this one host (mpirun's OMPI_COMM_WORLD_LOCAL_SIZE equals OMPI_COMM_WORLD_SIZE) and
// nobody chose a layer (no OMPI_MCA_pml: mpirun --mca pml X sets it), ob1 over shared memory is
// what a fabric would not beat here, so prt asks for it before MPI_Init reads the environment.
// True when it chose.
bool preferSharedMemoryOnOneHost() {
  const char* local = std::getenv("OMPI_COMM_WORLD_LOCAL_SIZE");
  const char* world = std::getenv("OMPI_COMM_WORLD_SIZE");
  if (std::getenv("OMPI_MCA_pml") || !local || !world || std::strcmp(local, world) != 0) return false;
  return ::setenv("OMPI_MCA_pml", "ob1", 0) == 0;
}

class MpiRanks final : public Ranks {
 public:
  MpiRanks() : sharedMemory_(preferSharedMemoryOnOneHost()) {
    int provided = 0;
    // Only the thread that runs the stages calls MPI, between stages.
    check(MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided), "MPI_Init_thread");
    MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
    shareCounters();
  }
  ~MpiRanks() override {
    // While an exception unwinds, other ranks may wait in a collective: stopAllRanks ends them.
    if (std::uncaught_exceptions() != 0) return;
    if (locked_) MPI_Win_unlock_all(window_);
    if (window_ != MPI_WIN_NULL) MPI_Win_free(&window_);
    MPI_Finalize();
  }
  int rank() const override { return rank_; }
  int size() const override { return size_; }
  bool exchanges() const override { return size_ > 1; }

  std::vector<std::string> gather(std::string mine, bool toAll) override {
    // Sizes first, then the bytes in rounds of at most kRound per rank, so that every count
    // and displacement fits MPI's int however large the records are.
    std::vector<uint64_t> sizes(size_t(size_), 0);
    const uint64_t n = mine.size();
    MPI_Request req;
    check(MPI_Iallgather(&n, 1, MPI_UINT64_T, sizes.data(), 1, MPI_UINT64_T, MPI_COMM_WORLD, &req), "MPI_Iallgather");
    await(req, "MPI_Iallgather");  // once it is done, every rank has come to the exchange
    const bool receive = toAll || rank_ == 0;
    std::vector<std::string> all(static_cast<size_t>(size_));
    if (receive)
      for (int r = 0; r < size_; ++r) all[size_t(r)].resize(r == rank_ ? 0 : sizes[size_t(r)]);
    const uint64_t round = std::min<uint64_t>(uint64_t(1) << 28, uint64_t(INT_MAX) / uint64_t(size_));
    const uint64_t largest = *std::max_element(sizes.begin(), sizes.end());
    std::vector<int> counts(static_cast<size_t>(size_)), displs(static_cast<size_t>(size_));
    std::vector<char> buf;
    for (uint64_t at = 0; at < largest; at += round) {
      int total = 0;
      for (int r = 0; r < size_; ++r) {
        const uint64_t s = sizes[size_t(r)];
        counts[size_t(r)] = int(s > at ? std::min(round, s - at) : 0);
        displs[size_t(r)] = total;
        total += counts[size_t(r)];
      }
      if (receive) buf.resize(size_t(total));
      const char* send = mine.data() + std::min<uint64_t>(at, n);
      const int count = counts[size_t(rank_)];
      if (toAll)
        check(MPI_Iallgatherv(send, count, MPI_BYTE, buf.data(), counts.data(), displs.data(), MPI_BYTE, MPI_COMM_WORLD,
                              &req),
              "MPI_Iallgatherv");
      else
        check(MPI_Igatherv(send, count, MPI_BYTE, buf.data(), counts.data(), displs.data(), MPI_BYTE, 0, MPI_COMM_WORLD,
                           &req),
              "MPI_Igatherv");
      await(req, "MPI_Igatherv", Wait::Transfer);
      if (!receive) continue;
      for (int r = 0; r < size_; ++r)
        if (r != rank_ && counts[size_t(r)] > 0)
          std::copy_n(buf.data() + displs[size_t(r)], counts[size_t(r)], all[size_t(r)].data() + at);
    }
    ++gathers_;
    if (receive)
      for (int r = 0; r < size_; ++r) received_ += r == rank_ ? 0 : sizes[size_t(r)];
    if (receive) all[size_t(rank_)] = std::move(mine);
    return receive ? all : std::vector<std::string>{};
  }

  uint64_t minimum(uint64_t v) override { return allReduce(v, MPI_MIN); }
  uint64_t sum(uint64_t v) override { return allReduce(v, MPI_SUM); }
  uint64_t allReduce(uint64_t v, MPI_Op op) {
    uint64_t out = v;
    MPI_Request req;
    check(MPI_Iallreduce(&v, &out, 1, MPI_UINT64_T, op, MPI_COMM_WORLD, &req), "MPI_Iallreduce");
    await(req, "MPI_Iallreduce");
    return out;
  }
  void barrier() override {
    MPI_Request req;
    check(MPI_Ibarrier(MPI_COMM_WORLD, &req), "MPI_Ibarrier");
    await(req, "MPI_Ibarrier");
  }

  uint64_t* chunkCounter(uint32_t slot) override {
    return counters_ && slot < kCounterSlots ? counters_ + slot : nullptr;
  }

  std::string transportChoice() const override {
    return sharedMemory_ ? "Open MPI's ob1 over shared memory, chosen for one host" : "";
  }

 private:
  // The chunk counters (Ranks::chunkCounter), when every rank runs on this host: an MPI-3
  // shared window of kCounterSlots uint64 on rank 0, which every rank maps, zeroed before any
  // rank reads it, open for loads and stores (a passive epoch) until the end. Ranks on several
  // hosts, or a window that cannot be made, leave the chunks split statically: on every rank
  // alike (the outcome is agreed).
  void shareCounters() {
    MPI_Comm host = MPI_COMM_NULL;
    if (MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, rank_, MPI_INFO_NULL, &host) != MPI_SUCCESS) return;
    int hostSize = 0;
    MPI_Comm_size(host, &hostSize);
    bool ok = false;
    if (hostSize == size_) {  // the same answer on every rank: all on one host, or not
      void* mine = nullptr;
      const MPI_Aint bytes = rank_ == 0 ? MPI_Aint(kCounterSlots * sizeof(uint64_t)) : 0;
      if (MPI_Win_allocate_shared(bytes, int(sizeof(uint64_t)), MPI_INFO_NULL, host, &mine, &window_) == MPI_SUCCESS) {
        MPI_Win_set_errhandler(window_, MPI_ERRORS_RETURN);
        MPI_Aint size = 0;
        int unit = 0;
        void* first = nullptr;
        locked_ = MPI_Win_lock_all(MPI_MODE_NOCHECK, window_) == MPI_SUCCESS;
        ok = locked_ && MPI_Win_shared_query(window_, 0, &size, &unit, &first) == MPI_SUCCESS && first != nullptr &&
             size >= MPI_Aint(kCounterSlots * sizeof(uint64_t));
        if (ok) {
          counters_ = static_cast<uint64_t*>(first);
          if (rank_ == 0) std::fill_n(counters_, kCounterSlots, uint64_t(0));
          MPI_Win_sync(window_);
        }
      }
    }
    MPI_Comm_free(&host);
    // Every rank uses the counters or none does; this also orders rank 0's zeros before any use.
    if (allReduce(ok ? 0 : 1, MPI_SUM) != 0) counters_ = nullptr;
    if (window_ != MPI_WIN_NULL) MPI_Win_sync(window_);
  }

  bool sharedMemory_ = false;
  int rank_ = 0, size_ = 1;
  MPI_Win window_ = MPI_WIN_NULL;
  bool locked_ = false;
  uint64_t* counters_ = nullptr;
};

}  // namespace

bool mpiBuilt() { return true; }

std::unique_ptr<Ranks> startMpi() {
  if (launcherRank() < 0) return nullptr;
  return std::make_unique<MpiRanks>();
}

void stopAllRanks(int code) {
  int up = 0, down = 0;
  MPI_Initialized(&up);
  MPI_Finalized(&down);
  if (up && !down) MPI_Abort(MPI_COMM_WORLD, code);
}

#else

bool mpiBuilt() { return false; }
std::unique_ptr<Ranks> startMpi() { return nullptr; }
void stopAllRanks(int) {}

#endif

}  // namespace prt::bake
