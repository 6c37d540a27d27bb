// A probe for MpiExactSum.* (mpi_exact_sum_test.cpp), started under `mpiexec -n 3`: every rank
// adds its terms to exact sums (core/exact_sum.h), combines them with ExactVector::allreduce and
// prints what it got, one line per rank: "rank R small BIG refused".
//   small   each rank adds 2^-10 · (rank + 1): the exact total 2^-10 · K(K + 1)/2.
//   BIG     ranks 0 and 1 add +0.75 · 2^32 2^23 times each (0.75 · 2^127 in fixed point: the largest
//           128-bit sums), rank 2 as often −0.75 · 2^32, the others nothing. Ranks 0 and 1 together
//           leave the 128-bit range, the total (0.75 · 2^55) does not: it must come out exactly,
//           whatever the order in which the ranks are combined.
//   refused every rank adds +0.75 · 2^32 2^23 times: the total leaves the range and every rank
//           must refuse it alike ("overflow"; "none" when it did not).
#include <cstdio>
#include <stdexcept>

#include "core/exact_sum.h"
#include "wavebrdf/communicator.h"

int main() {
    using wavebrdf::detail::ExactVector;
    const auto comm = wavebrdf::world_communicator();
    const int rank = comm->rank();
    constexpr long terms = 1L << 23;
    const double big = 0.75 * 0x1p32;

    ExactVector sums(2);
    sums.add(0, std::ldexp(double(rank + 1), -10));
    const double sign = rank < 2 ? 1.0 : rank == 2 ? -1.0 : 0.0;
    if (sign != 0.0)
        for (long i = 0; i < terms; ++i) sums.add(1, sign * big);
    bool big_refused = false;
    try {
        sums.allreduce(*comm);
    } catch (const std::overflow_error&) {
        big_refused = true;
    }

    ExactVector all(1);
    for (long i = 0; i < terms; ++i) all.add(0, big);
    const char* refused = "none";
    try {
        all.allreduce(*comm);
    } catch (const std::overflow_error&) {
        refused = "overflow";
    }
    if (big_refused)
        std::printf("rank %d %.17g overflow %s\n", rank, 0.0, refused);
    else
        std::printf("rank %d %.17g %.17g %s\n", rank, sums.value(0), sums.value(1), refused);
    return 0;
}
