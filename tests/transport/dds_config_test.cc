// The embedded configuration, its override rules and the RAII set-up, on the real Cyclone DDS.

#include "transport/dds_config.h"

#include <gtest/gtest.h>
#include <stdlib.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <stdexcept>
#include <string>

#include "tests/transport/transport_test_util.h"

namespace felt::transport {
namespace {

// Sets or clears CYCLONEDDS_URI for one test and restores it afterwards.
class ScopedUri {
 public:
  explicit ScopedUri(const char* value) {
    if (const char* old = getenv("CYCLONEDDS_URI")) saved_ = old, had_ = true;
    if (value) {
      setenv("CYCLONEDDS_URI", value, 1);
    } else {
      unsetenv("CYCLONEDDS_URI");
    }
  }
  ~ScopedUri() {
    if (had_) {
      setenv("CYCLONEDDS_URI", saved_.c_str(), 1);
    } else {
      unsetenv("CYCLONEDDS_URI");
    }
  }

 private:
  std::string saved_;
  bool had_ = false;
};

// A file in /tmp holding `text`, removed at the end of the test.
class TempFile {
 public:
  explicit TempFile(const std::string& text)
      : path_("/tmp/felt-dds-config" + testing::UniqueSuffix().substr(5) + ".xml") {
    std::ofstream(path_) << text;
  }
  ~TempFile() { std::remove(path_.c_str()); }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

std::string MessageOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "no error";
}

TEST(DdsConfigTest, TheEmbeddedConfigurationIsLoopbackUnicastWithAutoIndex) {
  const std::string& xml = DefaultLoopbackConfig();
  EXPECT_NE(xml.find("<NetworkInterface name=\"lo\"/>"), std::string::npos);
  EXPECT_NE(xml.find("<AllowMulticast>false</AllowMulticast>"), std::string::npos);
  EXPECT_NE(xml.find("<Peer address=\"127.0.0.1\"/>"), std::string::npos);
  EXPECT_NE(xml.find("<ParticipantIndex>auto</ParticipantIndex>"), std::string::npos);
  EXPECT_NE(xml.find("<MaxAutoParticipantIndex>30</MaxAutoParticipantIndex>"), std::string::npos);
}

TEST(DdsConfigTest, PrecedenceIsFileThenEnvironmentThenEmbedded) {
  DdsSettings settings;
  {
    ScopedUri uri(nullptr);
    EXPECT_EQ(ResolveConfig(settings).source, "embedded");
    EXPECT_EQ(ResolveConfig(settings).config, DefaultLoopbackConfig());
  }
  {
    ScopedUri uri("");  // empty counts as not set
    EXPECT_EQ(ResolveConfig(settings).source, "embedded");
  }
  ScopedUri uri("file:///nonexistent/cyclone.xml");
  EXPECT_EQ(ResolveConfig(settings).source, "CYCLONEDDS_URI");
  EXPECT_EQ(ResolveConfig(settings).config, "file:///nonexistent/cyclone.xml");
  TempFile file(DefaultLoopbackConfig());
  settings.config_file = file.path();
  EXPECT_EQ(ResolveConfig(settings).source, "file " + file.path());
  EXPECT_EQ(ResolveConfig(settings).config, DefaultLoopbackConfig());
}

TEST(DdsConfigTest, AMissingOrEmptyFileIsAnErrorNamingIt) {
  DdsSettings settings;
  settings.config_file = "/nonexistent/felt.xml";
  EXPECT_EQ(MessageOf([&] { ResolveConfig(settings); }),
            "--dds-config /nonexistent/felt.xml: cannot open the file");
  TempFile empty("");
  settings.config_file = empty.path();
  EXPECT_NE(MessageOf([&] { ResolveConfig(settings); }).find("not a Cyclone XML configuration"),
            std::string::npos);
}

TEST(DdsConfigTest, TheEmbeddedConfigurationCreatesADomainAndParticipant) {
  ScopedUri uri(nullptr);
  Participant participant(AcquireDomain(testing::TestDds()));
  EXPECT_GT(participant.get(), 0);
  EXPECT_EQ(participant.domain().config().source, "embedded");
  // A second acquisition shares the live instance (Cyclone allows one per domain and process).
  Participant second(AcquireDomain(testing::TestDds()));
  EXPECT_EQ(&participant.domain(), &second.domain());
}

TEST(DdsConfigTest, ABrokenConfigurationFileIsRefusedWithItsName) {
  ScopedUri uri(nullptr);
  TempFile file(
      "<CycloneDDS><Domain id=\"any\"><General><NoSuchElement>1</NoSuchElement>"
      "</General></Domain></CycloneDDS>");
  DdsSettings settings;
  settings.domain_id = testing::kTestDomain + 1;
  settings.config_file = file.path();
  const std::string message = MessageOf([&] { AcquireDomain(settings); });
  EXPECT_NE(message.find("DDS domain 43 with the file " + file.path() + " configuration"),
            std::string::npos)
      << message;
}

TEST(DdsConfigTest, OneDomainCannotHaveTwoConfigurationsInOneProcess) {
  ScopedUri uri(nullptr);
  auto domain = AcquireDomain(testing::TestDds());
  TempFile file(DefaultLoopbackConfig() + "<!-- another -->");
  DdsSettings settings = testing::TestDds();
  settings.config_file = file.path();
  EXPECT_NE(MessageOf([&] { AcquireDomain(settings); }).find("already in use in this process"),
            std::string::npos);
}

TEST(DdsConfigTest, DomainIdsAboveTheDdsRangeAreRefused) {
  DdsSettings settings;
  settings.domain_id = 231;
  EXPECT_NE(MessageOf([&] { AcquireDomain(settings); }).find("--domain 231"), std::string::npos);
}

TEST(DdsConfigTest, CheckDdsThrowsCycloneText) {
  EXPECT_EQ(CheckDds(5, "fine"), 5);
  EXPECT_EQ(MessageOf([] { CheckDds(DDS_RETCODE_BAD_PARAMETER, "dds_thing"); }),
            std::string("dds_thing: ") + dds_strretcode(DDS_RETCODE_BAD_PARAMETER));
}

TEST(DdsConfigTest, TopicNamesTakeAPrefixAndASuffix) {
  const TopicNames plain;
  EXPECT_EQ(plain.pointer, "felt/pointer");
  EXPECT_EQ(plain.force, "felt/force");
  EXPECT_EQ(plain.status, "felt/status");
  const TopicNames names = TopicNames::WithAffixes("lab/", "/test_1_2");
  EXPECT_EQ(names.pointer, "lab/felt/pointer/test_1_2");
  EXPECT_EQ(names.force, "lab/felt/force/test_1_2");
  EXPECT_EQ(names.status, "lab/felt/status/test_1_2");
}

TEST(DdsConfigTest, DeviceIdsAreCheckedWhenCopied) {
  char out[65];
  CopyId("left-hand", out, "id");
  EXPECT_STREQ(out, "left-hand");
  EXPECT_NE(MessageOf([&] { CopyId("", out, "device_id"); }).find("device_id \"\""),
            std::string::npos);
  EXPECT_NO_THROW(CopyId(std::string(64, 'a'), out, "id"));
  EXPECT_THROW(CopyId(std::string(65, 'a'), out, "id"), std::invalid_argument);
}

}  // namespace
}  // namespace felt::transport
