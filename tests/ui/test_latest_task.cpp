// ui/latest_task: only the newest request's result is delivered, busy() lasts until it is, supersede()
// answers at once, jobs learn they are superseded, and destruction waits for every job still running.
#include <QtTest>

#include <atomic>
#include <chrono>
#include <memory>
#include <thread>
#include <vector>

#include "ui/latest_task.h"

using residue::ui::LatestTask;

class TestLatestTask : public QObject {
  Q_OBJECT
 private slots:
  void onlyTheNewestIsDelivered() {
    QObject owner;
    std::vector<int> delivered;
    LatestTask<int> task(&owner, [&](int&& v) { delivered.push_back(v); });
    QVERIFY(!task.busy());
    // Older requests take longer: they finish after the newest and must still be dropped.
    for (int i = 0; i < 4; ++i)
      task.start([i](const LatestTask<int>::Token&) {
        std::this_thread::sleep_for(std::chrono::milliseconds(200 - 50 * i));
        return i;
      });
    QVERIFY(task.busy());
    QTRY_VERIFY_WITH_TIMEOUT(!task.busy(), 5000);
    QCOMPARE(delivered, std::vector<int>{3});
    // Nothing more arrives later from the superseded jobs.
    QTest::qWait(300);
    QCOMPARE(delivered, std::vector<int>{3});
  }

  void jobsLearnTheyAreSuperseded() {
    QObject owner;
    int delivered = 0;
    std::atomic<bool> saw_superseded{false};
    LatestTask<int> task(&owner, [&](int&&) { ++delivered; });
    task.start([&](const LatestTask<int>::Token& t) {
      for (int i = 0; i < 200 && !t.superseded(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
      saw_superseded = t.superseded();
      return 0;
    });
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
    task.supersede();  // e.g. the reference was closed: the panel answers at once
    QVERIFY(!task.busy());
    QTRY_VERIFY_WITH_TIMEOUT(saw_superseded.load(), 5000);
    QTest::qWait(100);
    QCOMPARE(delivered, 0);
  }

  void pendingTellsAPreviewWhetherToShow() {
    QObject owner;
    LatestTask<int> task(&owner, [](int&&) {});
    std::atomic<int> generation{-1};
    task.start([&](const LatestTask<int>::Token& t) {
      generation = t.generation();
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      return 1;
    });
    QTRY_VERIFY(generation.load() >= 0);
    QVERIFY(task.pending(generation));
    QTRY_VERIFY_WITH_TIMEOUT(!task.busy(), 5000);
    QVERIFY(!task.pending(generation));
  }

  void destructionWaitsForEveryRunningJob() {
    auto alive = std::make_shared<std::atomic<int>>(0);
    {
      QObject owner;
      LatestTask<int> task(&owner, [](int&&) {});
      for (int i = 0; i < 3; ++i)
        task.start([alive](const LatestTask<int>::Token&) {
          ++*alive;
          std::this_thread::sleep_for(std::chrono::milliseconds(150));
          --*alive;
          return 0;
        });
      QTRY_VERIFY(alive->load() > 0);
    }
    QCOMPARE(alive->load(), 0);
  }
};

QTEST_MAIN(TestLatestTask)
#include "test_latest_task.moc"
