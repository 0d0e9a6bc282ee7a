#include "base/report.h"

#include <sched.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "base/simd.h"

namespace felt::report {

double Percentile(std::vector<double> samples, double p) {
  if (samples.empty()) return std::nan("");
  std::sort(samples.begin(), samples.end());
  const double rank = std::ceil(p / 100.0 * static_cast<double>(samples.size()));
  const size_t index =
      static_cast<size_t>(std::clamp(rank, 1.0, static_cast<double>(samples.size())));
  return samples[index - 1];
}

double Median(std::vector<double> samples) { return Percentile(std::move(samples), 50.0); }

double ThreadCpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

double WallMs() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

std::string LoadAverage() {
  std::ifstream file("/proc/loadavg");
  std::string a, b, c;
  if (!(file >> a >> b >> c)) return "unknown";
  return a + " " + b + " " + c;
}

MachineInfo ReadMachineInfo() {
  MachineInfo info;
  info.cpus_online = sysconf(_SC_NPROCESSORS_ONLN);
  // CPU model: the first "model name" line.
  std::ifstream cpuinfo("/proc/cpuinfo");
  std::string line;
  while (std::getline(cpuinfo, line)) {
    if (line.rfind("model name", 0) == 0) {
      const size_t colon = line.find(':');
      info.cpu_model = colon == std::string::npos ? line : line.substr(colon + 2);
      break;
    }
  }
  if (info.cpu_model.empty()) info.cpu_model = "unknown";
  // Date, load, niceness.
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char date[32];
  std::strftime(date, sizeof(date), "%Y-%m-%dT%H:%M:%SZ", &utc);
  info.date_utc = date;
  info.load_average = LoadAverage();
  info.niceness = getpriority(PRIO_PROCESS, 0);
  // Affinity as a list of CPU numbers.
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof(set), &set) == 0) {
    for (int cpu = 0; cpu < CPU_SETSIZE; ++cpu) {
      if (!CPU_ISSET(cpu, &set)) continue;
      if (!info.affinity.empty()) info.affinity += ",";
      info.affinity += std::to_string(cpu);
    }
  }
  if (info.affinity.empty()) info.affinity = "unknown";
  info.vector_kernels = SimdLevelName(ActiveSimdLevel());
  return info;
}

std::string ReportHeader(std::string_view title, std::string_view command, const MachineInfo& start,
                         std::string_view load_at_end) {
  std::ostringstream out;
  out << "# " << title << "\n\n"
      << "Command: `" << command << "` (Release build, one thread)\n\n"
      << "- Machine: " << start.cpus_online << " CPUs online (nproc), " << start.cpu_model
      << "; this process: niceness " << start.niceness << ", CPUs " << start.affinity
      << "; sim vector kernels: " << start.vector_kernels << "\n"
      << "- Date: " << start.date_utc << "\n"
      << "- Load average (1, 5, 15 min) at the start: " << start.load_average
      << "; at the end: " << load_at_end << "\n\n";
  return out.str();
}

std::string Sig(double value, int digits) {
  if (!std::isfinite(value)) return "-";
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*g", digits, value);
  return buf;
}

std::string Fixed(double value, int decimals) {
  if (!std::isfinite(value)) return "-";
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, value);
  return buf;
}

Json MachineJson(const MachineInfo& machine) {
  return Json{{"cpus_online", machine.cpus_online},
              {"cpu_model", machine.cpu_model},
              {"date_utc", machine.date_utc},
              {"load_average", machine.load_average},
              {"niceness", machine.niceness},
              {"affinity", machine.affinity},
              {"vector_kernels", machine.vector_kernels}};
}

void AppendMachineJson(const MachineInfo& machine, std::string_view load_at_end, Json* report) {
  (*report)["machine"] = MachineJson(machine);
  (*report)["load_average_end"] = std::string(load_at_end);
}

std::string MarkdownTable(const std::vector<std::string>& header, const std::vector<bool>& right,
                          const std::vector<std::vector<std::string>>& rows) {
  std::string out = "|";
  for (const std::string& h : header) out += " " + h + " |";
  out += "\n|";
  for (size_t c = 0; c < header.size(); ++c) {
    out += c < right.size() && right[c] ? "---:|" : "---|";
  }
  out += "\n";
  for (const std::vector<std::string>& row : rows) {
    out += "|";
    for (const std::string& cell : row) out += " " + cell + " |";
    out += "\n";
  }
  return out;
}

namespace {

std::string CsvCell(const std::string& cell) {
  if (cell.find_first_of(",\"\n") == std::string::npos) return cell;
  std::string out = "\"";
  for (const char c : cell) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + "\"";
}

std::string CsvLine(const std::vector<std::string>& cells) {
  std::string out;
  for (size_t c = 0; c < cells.size(); ++c) {
    if (c > 0) out += ",";
    out += CsvCell(cells[c]);
  }
  return out + "\n";
}

}  // namespace

std::string CsvTable(const std::vector<std::string>& header,
                     const std::vector<std::vector<std::string>>& rows) {
  std::string out = CsvLine(header);
  for (const std::vector<std::string>& row : rows) out += CsvLine(row);
  return out;
}

void WriteTextFile(const std::string& path, const std::string& text) {
  const std::filesystem::path file(path);
  std::error_code error;
  if (file.has_parent_path()) std::filesystem::create_directories(file.parent_path(), error);
  std::ofstream out(file);
  out << text;
  out.flush();
  if (!out) throw std::runtime_error("cannot write " + path);
}

}  // namespace felt::report
