#include "base/report.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace felt::report {
namespace {

TEST(PercentileTest, NearestRank) {
  std::vector<double> hundred;
  for (int i = 100; i >= 1; --i) hundred.push_back(i);
  EXPECT_EQ(Percentile(hundred, 50.0), 50.0);
  EXPECT_EQ(Percentile(hundred, 99.0), 99.0);
  EXPECT_EQ(Percentile(hundred, 99.9), 100.0);
  EXPECT_EQ(Percentile(hundred, 100.0), 100.0);
  EXPECT_EQ(Percentile(hundred, 0.0), 1.0);
  EXPECT_EQ(Percentile(hundred, 150.0), 100.0);  // clamped to the largest
  EXPECT_EQ(Median({4.0, 1.0, 3.0, 2.0}), 2.0);  // the lower middle for an even count
  EXPECT_EQ(Median({7.0}), 7.0);
}

TEST(PercentileTest, NoSamplesIsNaN) {
  EXPECT_TRUE(std::isnan(Percentile({}, 50.0)));
  EXPECT_TRUE(std::isnan(Median({})));
}

TEST(MachineJsonTest, EveryField) {
  const Json json = MachineJson(ReadMachineInfo());
  for (const char* key : {"cpus_online", "cpu_model", "date_utc", "load_average", "niceness",
                          "affinity", "vector_kernels"}) {
    EXPECT_TRUE(json.contains(key)) << key;
  }
}

}  // namespace
}  // namespace felt::report
