#include "ui/tev_server.h"

#include <QTcpSocket>
#include <unistd.h>
#include <variant>

#include "core/util/error.h"

namespace residue::ui {

size_t TevServer::default_memory() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
  return pages > 0 && page > 0 ? static_cast<size_t>(pages) * static_cast<size_t>(page) / 4 : size_t{4} << 30;
}

TevServer::TevServer(QObject* parent, size_t max_bytes) : QObject(parent), images_(max_bytes) {
  connect(&server_, &QTcpServer::newConnection, this, &TevServer::accept);
}

TevServer::~TevServer() {
  // The sockets are server_'s children and die with it, after streams_: they must not call back into this.
  for (auto& entry : streams_) entry.first->disconnect(this);
  streams_.clear();
}

bool TevServer::listen(quint16 port, const QHostAddress& address) {
  error_.clear();
  if (server_.listen(address, port)) return true;
  error_ = tr("cannot listen for renderers on %1:%2 (%3); is tev or another Residue viewer running?")
               .arg(address.toString())
               .arg(port)
               .arg(server_.errorString());
  return false;
}

QString TevServer::errorString() const { return error_; }

void TevServer::accept() {
  while (QTcpSocket* socket = server_.nextPendingConnection()) {
    streams_.emplace(socket, ipc::TevPacketStream{});
    connect(socket, &QTcpSocket::readyRead, this, [this, socket] { receive(socket); });
    connect(socket, &QTcpSocket::disconnected, this, [this, socket] {
      streams_.erase(socket);
      socket->deleteLater();
    });
  }
}

void TevServer::receive(QTcpSocket* socket) {
  auto it = streams_.find(socket);
  if (it == streams_.end()) return;
  const QByteArray bytes = socket->readAll();
  try {
    it->second.feed({reinterpret_cast<const uint8_t*>(bytes.constData()), static_cast<size_t>(bytes.size())});
    while (auto packet = it->second.next()) handle(ipc::parse_tev_packet(*packet));
  } catch (const std::exception& e) {
    // The stream cannot be trusted after a bad packet (its framing may be off): drop this client only.
    emit protocolError(tr("renderer connection closed: %1").arg(QString::fromStdString(e.what())));
    streams_.erase(socket);
    socket->disconnect(this);
    socket->abort();
    socket->deleteLater();
  }
}

void TevServer::handle(const ipc::TevPacket& packet) {
  std::visit(
      [this](const auto& p) {
        using T = std::decay_t<decltype(p)>;
        if constexpr (std::is_same_v<T, ipc::OpenImage>) {
          emit openRequested(QString::fromStdString(p.path), QString::fromStdString(p.channel_selector), p.grab_focus);
        } else if constexpr (std::is_same_v<T, ipc::ReloadImage>) {
          emit reloadRequested(QString::fromStdString(p.name));
        } else if constexpr (std::is_same_v<T, ipc::CloseImage>) {
          images_.close(p.name);
          emit closeRequested(QString::fromStdString(p.name));
        } else if constexpr (std::is_same_v<T, ipc::CreateImage>) {
          images_.apply(p);
          emit liveImageChanged(QString::fromStdString(p.name), p.grab_focus);
        } else {
          if (!images_.apply(p).empty()) emit liveImageChanged(QString::fromStdString(p.name), p.grab_focus);
        }
      },
      packet);
}

}  // namespace residue::ui
