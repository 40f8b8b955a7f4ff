// TevServer: the viewer's end of tev's IPC protocol, so that renderers and scripts that stream to tev (pbrt-v4,
// Mitsuba, tev's Python and C++ clients) stream into Residue. It listens on the loopback interface (port 14158,
// tev's, by default), frames and decodes what each client sends (core/ipc/tev_protocol.h), keeps the streamed
// images (core/ipc/live_images.h) and says what happened; the window decides what to show. A malformed packet
// closes that client's connection with a message: the viewer itself goes on.
#pragma once

#include <QHostAddress>
#include <QObject>
#include <QString>
#include <QTcpServer>
#include <map>

#include "core/ipc/live_images.h"
#include "core/ipc/tev_protocol.h"

class QTcpSocket;

namespace residue::ui {

class TevServer : public QObject {
  Q_OBJECT
 public:
  // `max_bytes`: the streamed images' memory, all clients together (ipc::LiveImages); by default a quarter of
  // this machine's RAM.
  explicit TevServer(QObject* parent = nullptr, size_t max_bytes = default_memory());
  static size_t default_memory();
  ~TevServer() override;
  // Starts listening; false when it cannot (the port is taken: tev or another viewer), with errorString().
  bool listen(quint16 port = ipc::kTevDefaultPort, const QHostAddress& address = QHostAddress::LocalHost);
  bool listening() const { return server_.isListening(); }
  quint16 port() const { return server_.serverPort(); }
  QString errorString() const;
  const ipc::LiveImages& images() const { return images_; }
  int connections() const { return static_cast<int>(streams_.size()); }

 signals:
  void openRequested(QString path, QString channel_selector, bool grab_focus);
  void reloadRequested(QString name);
  void closeRequested(QString name);
  void liveImageChanged(QString name, bool grab_focus);  // created, or a rectangle of it updated
  void protocolError(QString message);  // the client was disconnected

 private:
  void accept();
  void receive(QTcpSocket* socket);
  void handle(const ipc::TevPacket& packet);

  QTcpServer server_;
  std::map<QTcpSocket*, ipc::TevPacketStream> streams_;
  ipc::LiveImages images_;
  QString error_;
};

}  // namespace residue::ui
