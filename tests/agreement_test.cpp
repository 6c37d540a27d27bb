// run_agreed and run_or_abort (communicator.h, docs/scale.md "Errors"): the one agreement on
// failures of recover, invert, table and the batch renderer. Several ranks are simulated by
// threads sharing a small in-process communicator (the MPI tests check the CLI end to end).
#include <gtest/gtest.h>

#include <condition_variable>
#include <cstring>
#include <functional>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "wavebrdf/communicator.h"

namespace {

using wavebrdf::Communicator;
using wavebrdf::RankFailed;
using wavebrdf::run_agreed;

// What the ranks (threads) share: one slot per rank and a reusable barrier.
struct Shared {
    explicit Shared(int size) : slots(static_cast<std::size_t>(size)), size(size) {}
    std::vector<std::vector<double>> slots;
    int size;
    std::mutex mutex;
    std::condition_variable cv;
    int waiting = 0;
    long generation = 0;

    void barrier() {
        std::unique_lock<std::mutex> lock(mutex);
        const long mine = generation;
        if (++waiting == size) {
            waiting = 0;
            ++generation;
            cv.notify_all();
        } else {
            cv.wait(lock, [&] { return generation != mine; });
        }
    }
};

// Rank `rank` of the threads sharing `shared`: sums in rank order, broadcasts by copy.
class ThreadCommunicator final : public Communicator {
public:
    ThreadCommunicator(Shared& shared, int rank) : m_shared(shared), m_rank(rank) {}
    int rank() const override { return m_rank; }
    int size() const override { return m_shared.size; }
    void allreduce_sum(double* values, std::size_t count) const override {
        m_shared.slots[std::size_t(m_rank)].assign(values, values + count);
        m_shared.barrier();
        for (std::size_t i = 0; i < count; ++i) {
            double sum = m_shared.slots[0][i];
            for (int r = 1; r < m_shared.size; ++r) sum += m_shared.slots[std::size_t(r)][i];
            values[i] = sum;
        }
        m_shared.barrier();
    }
    void broadcast(double* values, std::size_t count, int root) const override {
        if (m_rank == root) m_shared.slots[std::size_t(root)].assign(values, values + count);
        m_shared.barrier();
        if (m_rank != root && count > 0) std::memcpy(values, m_shared.slots[std::size_t(root)].data(), count * 8);
        m_shared.barrier();
    }
    std::vector<double> gather(const std::vector<double>&, int) const override { throw std::logic_error("unused"); }
    void gather_words(const std::uint64_t*, std::size_t, std::uint64_t*, int) const override {
        throw std::logic_error("unused");
    }
    void broadcast_words(std::uint64_t*, std::size_t, int) const override { throw std::logic_error("unused"); }
    bool any(bool flag) const override {
        double f = flag ? 1.0 : 0.0;
        allreduce_sum(&f, 1);
        return f != 0.0;
    }
    void barrier() const override { m_shared.barrier(); }
    [[noreturn]] void abort(int) const override { std::abort(); }

private:
    Shared& m_shared;
    int m_rank;
};

// What one rank saw of an agreement.
struct Outcome {
    bool threw = false;
    bool rank_failed = false;
    int failed_rank = -1;
    std::string what, message;
    bool has_cause = false;
    bool cause_is_domain_error = false;
};

// Runs `body(comm)` on `size` threads, each its own rank, and returns what each saw.
std::vector<Outcome> on_ranks(int size, const std::function<void(const Communicator&)>& body) {
    Shared shared(size);
    std::vector<Outcome> outcomes(static_cast<std::size_t>(size));
    std::vector<std::thread> threads;
    for (int r = 0; r < size; ++r)
        threads.emplace_back([&, r] {
            const ThreadCommunicator comm(shared, r);
            Outcome& o = outcomes[std::size_t(r)];
            try {
                body(comm);
            } catch (const RankFailed& e) {
                o.threw = o.rank_failed = true;
                o.failed_rank = e.failed_rank();
                o.what = e.what();
                o.message = e.message();
                o.has_cause = e.cause() != nullptr;
                if (o.has_cause) try {
                        std::rethrow_exception(e.cause());
                    } catch (const std::domain_error&) {
                        o.cause_is_domain_error = true;
                    } catch (...) {}
            } catch (const std::exception& e) {
                o.threw = true;
                o.what = e.what();
            }
        });
    for (std::thread& t : threads) t.join();
    return outcomes;
}

TEST(Agreement, OneRankFailingAloneFailsEveryRankWithItsMessage) {
    const auto outcomes = on_ranks(3, [](const Communicator& comm) {
        run_agreed(comm, [&] {
            if (comm.rank() == 1) throw std::domain_error("share 1 is bad");
        });
    });
    for (int r = 0; r < 3; ++r) {
        const Outcome& o = outcomes[std::size_t(r)];
        ASSERT_TRUE(o.rank_failed) << "rank " << r << ": " << o.what;
        EXPECT_EQ(o.failed_rank, 1);
        EXPECT_EQ(o.what, "rank 1: share 1 is bad");
        EXPECT_EQ(o.message, "share 1 is bad");
        // The failing rank keeps its own exception (its type), the others have none.
        EXPECT_EQ(o.has_cause, r == 1);
        EXPECT_EQ(o.cause_is_domain_error, r == 1);
    }
}

TEST(Agreement, TheLowestFailingRankIsReportedAndRankZeroHasNoPrefix) {
    const auto outcomes = on_ranks(3, [](const Communicator& comm) {
        run_agreed(comm, [&] { throw std::invalid_argument("bad option on rank " + std::to_string(comm.rank())); });
    });
    for (const Outcome& o : outcomes) {
        ASSERT_TRUE(o.rank_failed) << o.what;
        EXPECT_EQ(o.failed_rank, 0);
        EXPECT_EQ(o.what, "bad option on rank 0");
    }
}

TEST(Agreement, NoFailureNoThrowAndAnInnerAgreementPassesThroughUnchanged) {
    auto outcomes = on_ranks(2, [](const Communicator& comm) { run_agreed(comm, [] {}); });
    for (const Outcome& o : outcomes) EXPECT_FALSE(o.threw) << o.what;
    // An agreement inside an agreement (a command wrapped whole, its checks agreed inside; a
    // failure amid run_or_abort that was agreed): the inner failure is reported, not "rank 0".
    outcomes = on_ranks(2, [](const Communicator& comm) {
        run_agreed(comm, [&] {
            wavebrdf::run_or_abort(comm, [&] {
                run_agreed(comm, [&] {
                    if (comm.rank() == 1) throw std::domain_error("inner");
                });
            });
        });
    });
    for (int r = 0; r < 2; ++r) {
        const Outcome& o = outcomes[std::size_t(r)];
        ASSERT_TRUE(o.rank_failed) << o.what;
        EXPECT_EQ(o.failed_rank, 1);
        EXPECT_EQ(o.what, "rank 1: inner");
        EXPECT_EQ(o.cause_is_domain_error, r == 1);
    }
    // A rank's own failure is preferred over another's agreed one.
    outcomes = on_ranks(2, [](const Communicator& comm) {
        run_agreed(comm, [&] {
            if (comm.rank() == 0) throw RankFailed(0, "old");
            throw std::runtime_error("own");
        });
    });
    for (const Outcome& o : outcomes) {
        EXPECT_EQ(o.failed_rank, 1);
        EXPECT_EQ(o.what, "rank 1: own");
    }
}

TEST(Agreement, OneRankPropagatesTheExceptionUnchanged) {
    EXPECT_THROW(run_agreed(wavebrdf::serial_communicator(), [] { throw std::domain_error("x"); }), std::domain_error);
    EXPECT_THROW(wavebrdf::run_or_abort(wavebrdf::serial_communicator(), []() -> int { throw std::domain_error("x"); }),
                 std::domain_error);
    EXPECT_NO_THROW(run_agreed(wavebrdf::serial_communicator(), [] {}));
}

}  // namespace
