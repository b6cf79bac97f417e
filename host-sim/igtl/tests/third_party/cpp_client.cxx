// A client built on the reference C++ library (Debian's libopenigtlink-dev, 1.11, protocol
// version 2): reads the robot's pose (TRANSFORM "Robot", CRC checked by the library),
// measures the round trip of GET_TRANS queries, sends a target 2 mm away and times the
// pose reaching it, then sends the start pose back.
//
//   cpp_client HOST PORT [TOLERANCE_MM]
//
// Prints "cpp: ..." figures; exits 1 on any failure.

#include "igtlClientSocket.h"
#include "igtlMessageHeader.h"
#include "igtlTransformMessage.h"
#include "igtl_header.h"
#include "igtl_util.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

using Clock = std::chrono::steady_clock;

static int fail(const char* what) {
  std::fprintf(stderr, "cpp: FAIL: %s\n", what);
  return 1;
}

struct Client {
  igtl::ClientSocket::Pointer socket;
  igtl::MessageHeader::Pointer header = igtl::MessageHeader::New();
  int crc_checked = 0;
  int received = 0;

  // Reads messages until a TRANSFORM from `device` arrives (its matrix in `m`, CRC checked)
  // or `timeout_s` passes. Other messages are skipped. A TRANSFORM with an empty body (no
  // data) gives `empty` = true.
  bool read_transform(const char* device, igtl::Matrix4x4& m, double timeout_s, bool* empty = nullptr) {
    auto end = Clock::now() + std::chrono::duration<double>(timeout_s);
    while (Clock::now() < end) {
      header->InitPack();
      int r = socket->Receive(header->GetPackPointer(), header->GetPackSize());
      if (r == 0) return false;  // closed or timed out
      if (r != header->GetPackSize()) return false;
      header->Unpack();
      received++;
      bool wanted = std::strcmp(header->GetDeviceType(), "TRANSFORM") == 0 &&
                    std::strcmp(header->GetDeviceName(), device) == 0;
      if (!wanted) {
        socket->Skip(header->GetBodySizeToRead(), 0);
        continue;
      }
      if (header->GetBodySizeToRead() == 0) {
        if (empty) *empty = true;
        return true;
      }
      igtl::TransformMessage::Pointer t = igtl::TransformMessage::New();
      t->SetMessageHeader(header);
      t->AllocatePack();
      socket->Receive(t->GetPackBodyPointer(), t->GetPackBodySize());
      if (!(t->Unpack(1) & igtl::MessageHeader::UNPACK_BODY)) {
        std::fprintf(stderr, "cpp: CRC check failed on TRANSFORM %s\n", device);
        return false;
      }
      crc_checked++;
      t->GetMatrix(m);
      if (empty) *empty = false;
      return true;
    }
    return false;
  }

  void send_transform(const char* device, igtl::Matrix4x4& m) {
    igtl::TransformMessage::Pointer t = igtl::TransformMessage::New();
    t->SetDeviceName(device);
    t->SetMatrix(m);
    t->Pack();
    socket->Send(t->GetPackPointer(), t->GetPackSize());
  }

  // STT_TRANS: start the pose stream (header only; the library has no class for it, so the
  // header is written with its C API).
  void send_stt_trans(const char* device) {
    igtl_header h;
    std::memset(&h, 0, sizeof(h));
    h.version = IGTL_HEADER_VERSION;
    std::strncpy(h.name, "STT_TRANS", IGTL_HEADER_TYPE_SIZE);
    std::strncpy(h.device_name, device, IGTL_HEADER_DEVSIZE);
    h.timestamp = 0;
    h.body_size = 0;
    h.crc = crc64(0, 0, 0);
    igtl_header_convert_byte_order(&h);
    socket->Send(&h, IGTL_HEADER_SIZE);
  }

  void send_get_trans(const char* device) {
    igtl::GetTransformMessage::Pointer g = igtl::GetTransformMessage::New();
    g->SetDeviceName(device);
    g->Pack();
    socket->Send(g->GetPackPointer(), g->GetPackSize());
  }
};

static double distance_mm(igtl::Matrix4x4& a, igtl::Matrix4x4& b) {
  double d = 0;
  for (int i = 0; i < 3; i++) d += (a[i][3] - b[i][3]) * (a[i][3] - b[i][3]);
  return std::sqrt(d);
}

int main(int argc, char* argv[]) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s HOST PORT [TOLERANCE_MM]\n", argv[0]);
    return 2;
  }
  const double tol_mm = argc > 3 ? std::atof(argv[3]) : 0.05;
  Client c;
  c.socket = igtl::ClientSocket::New();
  if (c.socket->ConnectToServer(argv[1], std::atoi(argv[2])) != 0) return fail("cannot connect");
  c.socket->SetReceiveTimeout(5000);

  // The measured pose: asked for, and streamed from now on (STT_TRANS; a server that
  // pushes the pose already answers it with RTS_TRANS and goes on).
  igtl::Matrix4x4 start;
  c.send_stt_trans("Robot");
  c.send_get_trans("Robot");
  if (!c.read_transform("Robot", start, 5.0)) return fail("no TRANSFORM Robot within 5 s");

  // Round trip of a query whose answer is unique: GET_TRANS for a device without data is
  // answered with an empty TRANSFORM of that name (protocol page "Query").
  std::vector<double> rtt_us;
  for (int i = 0; i < 200; i++) {
    igtl::Matrix4x4 unused;
    bool empty = false;
    auto t0 = Clock::now();
    c.send_get_trans("Probe");
    if (!c.read_transform("Probe", unused, 5.0, &empty)) return fail("no answer to GET_TRANS Probe");
    rtt_us.push_back(std::chrono::duration<double, std::micro>(Clock::now() - t0).count());
    if (!empty) return fail("GET_TRANS Probe answered with data");
  }
  std::sort(rtt_us.begin(), rtt_us.end());

  // A target 2 mm along -y from the start; wait for the pose to reach it.
  igtl::Matrix4x4 goal;
  std::memcpy(goal, start, sizeof(goal));
  goal[1][3] -= 2.0f;
  auto t0 = Clock::now();
  c.send_transform("Target", goal);
  double reached_ms = -1, last = 1e9;
  while (std::chrono::duration<double>(Clock::now() - t0).count() < 10.0) {
    igtl::Matrix4x4 m;
    if (!c.read_transform("Robot", m, 10.0)) break;
    last = distance_mm(m, goal);
    if (last <= tol_mm) {
      reached_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
      break;
    }
  }
  if (reached_ms < 0) {
    std::fprintf(stderr, "cpp: pose %.4f mm from the target after 10 s\n", last);
    return fail("target not reached");
  }
  c.send_transform("Target", start);
  igtl::Matrix4x4 m;
  bool back = false;
  auto t1 = Clock::now();
  while (std::chrono::duration<double>(Clock::now() - t1).count() < 10.0 && c.read_transform("Robot", m, 10.0)) {
    if (distance_mm(m, start) <= tol_mm) { back = true; break; }
  }
  if (!back) return fail("start pose not reached again");

  std::printf(
      "cpp: GET_TRANS round trip over 200 queries: median %.0f us, p95 %.0f us, max %.0f us\n",
      rtt_us[rtt_us.size() / 2], rtt_us[rtt_us.size() * 95 / 100], rtt_us.back());
  std::printf("cpp: 2 mm target reached (within %.3f mm) in %.1f ms\n", tol_mm, reached_ms);
  std::printf("cpp: %d messages received, %d TRANSFORM bodies CRC-checked by libOpenIGTLink\n",
              c.received, c.crc_checked);
  c.socket->CloseSocket();
  std::printf("cpp: OK\n");
  return 0;
}
