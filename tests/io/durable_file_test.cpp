// io::durable_file: a durable replacement leaves exactly the new bytes and no
// temporary file; a failure throws FileError naming the path and leaves the old
// file as it was.
#include "lmf/io/durable_file.hpp"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include <gtest/gtest.h>

namespace {

namespace fs = std::filesystem;

std::string contents(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::path(::testing::TempDir()) / ("lmf_durable_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

TEST(DurableFile, ReplaceWritesTheNewBytesAndLeavesNoTemporary) {
  const fs::path dir = fresh_dir("replace");
  const fs::path file = dir / "state";
  lmf::io::replace_file_durably(file, "first");
  EXPECT_EQ(contents(file), "first");
  const std::string binary("a\0b\xff", 4);
  lmf::io::replace_file_durably(file, binary);
  EXPECT_EQ(contents(file), binary);
  EXPECT_FALSE(fs::exists(dir / "state.tmp"));
  fs::remove_all(dir);
}

TEST(DurableFile, AFailedReplaceNamesThePathAndKeepsTheOldFile) {
  const fs::path dir = fresh_dir("fail");
  const fs::path file = dir / "state";
  lmf::io::replace_file_durably(file, "old");
  // The temporary's name is taken by a directory: it cannot be created.
  fs::create_directory(dir / "state.tmp");
  try {
    lmf::io::replace_file_durably(file, "new");
    FAIL() << "expected io::FileError";
  } catch (const lmf::io::FileError& e) {
    EXPECT_NE(std::string(e.what()).find((dir / "state.tmp").string()), std::string::npos) << e.what();
  }
  EXPECT_EQ(contents(file), "old");
  EXPECT_THROW(lmf::io::sync_directory(dir / "missing"), lmf::io::FileError);
  EXPECT_THROW(lmf::io::write_file_synced(dir / "missing" / "f", "x"), lmf::io::FileError);
  fs::remove_all(dir);
}

}  // namespace
