// The shares of the observations over ranks and the serial communicator
// (include/wavebrdf/communicator.h). The MPI communicator is tested under mpirun (mpi_test).
#include <gtest/gtest.h>

#include <array>
#include <set>
#include <stdexcept>
#include <vector>

#include "wavebrdf/communicator.h"

namespace wavebrdf {
namespace {

TEST(CommunicatorTest, SharesAreBalancedContiguousAndCoverEverything) {
    for (std::size_t count : {0u, 1u, 7u, 100u, 101u})
        for (int size = 1; size <= 9; ++size) {
            std::size_t next = 0, smallest = count + 1, largest = 0;
            for (int rank = 0; rank < size; ++rank) {
                const Share share = share_of(count, rank, size);
                EXPECT_EQ(share.begin, next) << count << " items, rank " << rank << " of " << size;
                next = share.end;
                smallest = std::min(smallest, share.size());
                largest = std::max(largest, share.size());
            }
            EXPECT_EQ(next, count);
            EXPECT_LE(largest - smallest, 1u);
        }
    EXPECT_THROW(share_of(10, 2, 2), std::invalid_argument);
    EXPECT_THROW(share_of(10, -1, 2), std::invalid_argument);
    EXPECT_THROW(share_of(10, 0, 0), std::invalid_argument);
}

TEST(CommunicatorTest, ObservationShareKeepsEveryWavelengthOfAPositionTogether) {
    // Three wavelengths at each of five positions, wavelength-major (as a study might order them).
    std::vector<std::array<double, 2>> positions;
    for (int l = 0; l < 3; ++l)
        for (int p = 0; p < 5; ++p) positions.push_back({{1.5 * p, -2.0 * p}});
    std::set<std::size_t> seen;
    for (int rank = 0; rank < 2; ++rank) {
        const auto mine = observation_share(positions, rank, 2);
        std::set<std::array<double, 2>> mine_positions;
        for (std::size_t i : mine) {
            EXPECT_TRUE(seen.insert(i).second) << "observation " << i << " held twice";
            mine_positions.insert(positions[i]);
        }
        // Rank 0 holds the first three positions (15 = 3 + 2 over 2 ranks is 3 and 2), rank 1 the rest.
        EXPECT_EQ(mine_positions.size(), rank == 0 ? 3u : 2u);
        EXPECT_EQ(mine.size(), 3 * mine_positions.size());
        for (std::size_t i = 0; i < positions.size(); ++i)
            EXPECT_EQ(mine_positions.count(positions[i]) == 1, std::find(mine.begin(), mine.end(), i) != mine.end());
    }
    EXPECT_EQ(seen.size(), positions.size());
    EXPECT_EQ(observation_share(positions, 0, 1).size(), positions.size());
    EXPECT_TRUE(observation_share(positions, 7, 8).empty());  // more ranks than positions
}

TEST(CommunicatorTest, SerialCommunicatorIsOneRankAndLeavesValuesAlone) {
    const Communicator& serial = serial_communicator();
    EXPECT_EQ(serial.rank(), 0);
    EXPECT_EQ(serial.size(), 1);
    std::vector<double> values{1.0, -2.5, 3e300};
    serial.allreduce_sum(values);
    serial.broadcast(values);
    EXPECT_EQ(values, (std::vector<double>{1.0, -2.5, 3e300}));
    EXPECT_EQ(serial.gather(values), values);
    EXPECT_TRUE(serial.any(true));
    EXPECT_FALSE(serial.any(false));
    EXPECT_THROW(serial.broadcast(values, 1), std::invalid_argument);
    // Not started by mpirun (the tests never are): the world is this one process.
    EXPECT_EQ(world_communicator()->size(), 1);
}

}  // namespace
}  // namespace wavebrdf
