// ui/latest_task: only the newest request's result is delivered, busy() lasts until it is, supersede()
// answers at once, jobs learn they are superseded, and destruction waits for every job still running.
// Jobs wait on gates the test opens, and the test waits on what the jobs and the pool report: no fixed sleeps.
#include <QtTest>

#include <QThreadPool>
#include <atomic>
#include <memory>
#include <thread>
#include <vector>

#include "ui/latest_task.h"

using residue::ui::LatestTask;

namespace {

// A job's gate: closed until the test opens it.
struct Gate {
  std::atomic<bool> open{false};
  void release() {
    open = true;
    open.notify_all();
  }
  void wait() const { open.wait(false); }
};

// Every job of the pool has ended, and what the ends posted to this thread (the deliveries) has been handled.
void settle() {
  QThreadPool::globalInstance()->waitForDone();
  QCoreApplication::sendPostedEvents();
  QCoreApplication::processEvents();
}

}  // namespace

class TestLatestTask : public QObject {
  Q_OBJECT
 private slots:
  void initTestCase() {
    // Jobs here block on gates: enough pool threads that every one of them runs at once, whatever the cores.
    QThreadPool::globalInstance()->setMaxThreadCount(8);
  }

  void onlyTheNewestIsDelivered() {
    QObject owner;
    std::vector<int> delivered;
    LatestTask<int> task(&owner, [&](int&& v) { delivered.push_back(v); });
    QVERIFY(!task.busy());
    Gate gates[4];
    for (int i = 0; i < 4; ++i)
      task.start([i, &gates](const LatestTask<int>::Token&) {
        gates[i].wait();
        return i;
      });
    QVERIFY(task.busy());
    // The newest finishes first; the older ones after it, and must still be dropped.
    gates[3].release();
    QTRY_VERIFY_WITH_TIMEOUT(!task.busy(), 10000);
    QCOMPARE(delivered, std::vector<int>{3});
    for (int i = 0; i < 3; ++i) gates[i].release();
    settle();
    QCOMPARE(delivered, std::vector<int>{3});
  }

  void jobsLearnTheyAreSuperseded() {
    QObject owner;
    int delivered = 0;
    std::atomic<bool> started{false}, saw_superseded{false};
    LatestTask<int> task(&owner, [&](int&&) { ++delivered; });
    task.start([&](const LatestTask<int>::Token& t) {
      started = true;
      while (!t.superseded()) std::this_thread::yield();  // works until it is no longer wanted
      saw_superseded = true;
      return 0;
    });
    QTRY_VERIFY_WITH_TIMEOUT(started.load(), 10000);
    task.supersede();  // e.g. the reference was closed: the panel answers at once
    QVERIFY(!task.busy());
    settle();
    QVERIFY(saw_superseded.load());
    QCOMPARE(delivered, 0);
  }

  void pendingTellsAPreviewWhetherToShow() {
    QObject owner;
    LatestTask<int> task(&owner, [](int&&) {});
    std::atomic<int> generation{-1};
    Gate gate;
    task.start([&](const LatestTask<int>::Token& t) {
      generation = t.generation();
      gate.wait();
      return 1;
    });
    QTRY_VERIFY_WITH_TIMEOUT(generation.load() >= 0, 10000);
    QVERIFY(task.pending(generation));
    gate.release();
    QTRY_VERIFY_WITH_TIMEOUT(!task.busy(), 10000);
    QVERIFY(!task.pending(generation));
  }

  void destructionWaitsForEveryRunningJob() {
    auto alive = std::make_shared<std::atomic<int>>(0);
    Gate gate;
    std::atomic<bool> destroying{false};
    // Opens the jobs' gate only once the task is being destroyed: a destructor that did not wait would return
    // while they are still held.
    std::thread opener([&] {
      destroying.wait(false);
      gate.release();
    });
    {
      QObject owner;
      LatestTask<int> task(&owner, [](int&&) {});
      for (int i = 0; i < 3; ++i)
        task.start([alive, &gate](const LatestTask<int>::Token&) {
          ++*alive;
          gate.wait();
          --*alive;
          return 0;
        });
      QTRY_VERIFY_WITH_TIMEOUT(alive->load() == 3, 10000);
      // Destroyed before the task (declared after it): marks the start of the task's destruction.
      struct Mark {
        std::atomic<bool>& flag;
        ~Mark() {
          flag = true;
          flag.notify_all();
        }
      } mark{destroying};
    }
    QCOMPARE(alive->load(), 0);
    opener.join();
  }
};

QTEST_MAIN(TestLatestTask)
#include "test_latest_task.moc"
