// The viewer's scripting options, run as a script runs them (the residue binary, offscreen): a value outside
// what an option takes is refused at once, exit 2, naming it; a script whose export fails, or whose --ab or
// --screenshot-when cannot be met, ends with an error instead of exiting 0 or never quitting (issue 49, items
// 10 and 21).
#include <QProcess>
#include <QTemporaryDir>
#include <QtTest>
#include <filesystem>

namespace {

const QString kRoom = QString(RESIDUE_SOURCE_RESOURCES) + "/examples/room/noisy.exr";

struct Run {
  int exit_code = -1;
  QString output;
  bool finished = false;
};

Run viewer(const QStringList& args, int timeout_ms = 120000) {
  QProcess p;
  p.setProcessChannelMode(QProcess::MergedChannels);
  QProcessEnvironment env = QProcessEnvironment::systemEnvironment();
  env.insert("QT_QPA_PLATFORM", "offscreen");
  env.insert("RESIDUE_SETTINGS_ISOLATED", "1");
  p.setProcessEnvironment(env);
  p.start(RESIDUE_VIEWER_PATH, QStringList{"--no-ipc"} + args);
  Run r;
  r.finished = p.waitForFinished(timeout_ms);
  if (!r.finished) p.kill(), p.waitForFinished(5000);
  r.exit_code = p.exitCode();
  r.output = QString::fromUtf8(p.readAll());
  return r;
}

}  // namespace

class ViewerOptionsTest : public QObject {
  Q_OBJECT
 private slots:
  void badValuesAreRefusedNamingTheOption_data() {
    QTest::addColumn<QStringList>("args");
    QTest::addColumn<QString>("says");
    QTest::newRow("tile 0") << QStringList{"--tile", "0"} << "--tile 0";
    QTest::newRow("tile abc") << QStringList{"--tile", "abc"} << "--tile abc";
    QTest::newRow("zoom 0") << QStringList{"--zoom", "0"} << "--zoom 0";
    QTest::newRow("zoom -5") << QStringList{"--zoom", "-5"} << "--zoom -5";
    QTest::newRow("exposure nan") << QStringList{"--exposure", "nan"} << "--exposure nan";
    QTest::newRow("size huge") << QStringList{"--size", "100000x100000"} << "--size 100000x100000";
    QTest::newRow("ab") << QStringList{"--ab", "0,x"} << "--ab 0,x";
    QTest::newRow("progress 7") << QStringList{"--screenshot-when", "progress:7", "--screenshot", "x.png"}
                                << "--screenshot-when progress:7";
    QTest::newRow("layout") << QStringList{"--layout", "grid"} << "--layout grid";
    QTest::newRow("tab") << QStringList{"--tab", "Résultats"} << "--tab";
  }
  void badValuesAreRefusedNamingTheOption() {
    QFETCH(QStringList, args);
    QFETCH(QString, says);
    const Run r = viewer(QStringList{kRoom} + args, 30000);
    QVERIFY2(r.finished, qPrintable(r.output));
    QCOMPARE(r.exit_code, 2);
    QVERIFY2(r.output.contains(says), qPrintable(r.output));
  }

  // --ab naming results that do not exist ended in a viewer that never quit.
  void abBeyondTheResultsFails() {
    QTemporaryDir dir;
    const Run r = viewer({kRoom, "--ab", "99,100", "--screenshot", dir.filePath("shot.png")});
    QVERIFY2(r.finished, "the viewer quit");
    QCOMPARE(r.exit_code, 2);
    QVERIFY2(r.output.contains("--ab 99,100: there are"), qPrintable(r.output));
  }

  // --export-all into a folder that already holds the files exited 0.
  void exportThatFailsEndsWithAnError() {
    QTemporaryDir dir;
    const QString out = dir.filePath("export");
    const Run first = viewer({kRoom, "--export-all", out, "--screenshot", dir.filePath("a.png")});
    QVERIFY2(first.finished && first.exit_code == 0, qPrintable(first.output));
    const Run again = viewer({kRoom, "--export-all", out, "--screenshot", dir.filePath("b.png")});
    QVERIFY2(again.finished, "the viewer quit");
    QCOMPARE(again.exit_code, 1);
    QVERIFY2(again.output.contains("--export-all"), qPrintable(again.output));
  }
};

QTEST_MAIN(ViewerOptionsTest)
#include "test_viewer_options.moc"
