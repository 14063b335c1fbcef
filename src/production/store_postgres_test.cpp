// The results store's cases (store_cases.h) on a real PostgreSQL server,
// which the CTest fixture tests/production/postgres_fixture.sh starts.
// Usage: store_postgres_test FIXTURE_FOLDER. Exits 77 (CTest's
// SKIP_RETURN_CODE for this test) with the fixture's reason when it could
// not start a server, so the test is reported skipped, never passed.
#include "store_cases.h"

#include <cstdio>
#include <fstream>

namespace xgauge {
namespace {

std::string g_url;
std::vector<std::string> urls() { return {g_url}; }

using store_cases::StoreTest;
INSTANTIATE_TEST_SUITE_P(Postgres, StoreTest, ::testing::ValuesIn(urls()));

}  // namespace
}  // namespace xgauge

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s FIXTURE_FOLDER [gtest flags]\n", argv[0]);
    return 2;
  }
  const std::filesystem::path folder = argv[1];
  if (std::ifstream skip(folder / "skip"); skip) {
    std::string reason;
    std::getline(skip, reason);
    std::printf("SKIPPED: no PostgreSQL server: %s\n", reason.c_str());
    return 77;
  }
  if (!xgauge::sql::postgresAvailable()) {
    std::printf("SKIPPED: this build has no PostgreSQL support (libpqxx-dev not found)\n");
    return 77;
  }
  std::ifstream url(folder / "url");
  if (!std::getline(url, xgauge::g_url)) {
    std::fprintf(stderr, "%s: neither url nor skip: did the fixture run?\n", folder.c_str());
    return 1;
  }
  --argc, ++argv;  // gtest sees the flags after the folder
  argv[0] = argv[-1];
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
