#pragma once
// A gtest fixture whose every test has an empty folder of its own under the temporary folder
// (the process id and the test's name in its name, so parallel ctest runs never share one),
// removed after the test.

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>

namespace posthaste::test {

class ScratchFolderTest : public ::testing::Test {
   protected:
    /// `prefix`: the folder's name before the process id and the test's name.
    explicit ScratchFolderTest(std::string prefix) : prefix_(std::move(prefix)) {}

    void SetUp() override
    {
        dir_ = std::filesystem::temp_directory_path() /
               (prefix_ + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        std::filesystem::create_directories(dir_);
    }
    void TearDown() override { std::filesystem::remove_all(dir_); }

    /// A file's path in the test's folder.
    std::string path(const std::string &name) const { return (dir_ / name).string(); }

    std::filesystem::path dir_;

   private:
    std::string prefix_;
};

}  // namespace posthaste::test
