// Reads the LCM log of pose_log_writer.cpp with LCM's Java library and finds the types as
// lcm-spy does: lcm.spy.LCMTypeDatabase searches the jars named by CLASSPATH (here
// omnipose_lcm_types.jar) for LCM classes and keys them by fingerprint; the messages are
// decoded and read through reflection, the way lcm-spy shows them. Exits 1 on a mismatch.
// usage: CLASSPATH=<omnipose_lcm_types.jar> java -cp <lcm.jar>:<this class> DecodePoseLog <log>
import java.nio.ByteBuffer;

public class DecodePoseLog {
  static void check(boolean condition, String what) {
    if (!condition) {
      System.out.println("DecodePoseLog: FAILED: " + what);
      System.exit(1);
    }
  }

  public static void main(String[] args) throws Exception {
    lcm.spy.LCMTypeDatabase types = new lcm.spy.LCMTypeDatabase();
    lcm.logging.Log log = new lcm.logging.Log(args[0], "r");
    int poses = 0;
    int events = 0;
    double[] axis = {1.0 / 3.0, 2.0 / 3.0, 2.0 / 3.0};
    while (true) {
      lcm.logging.Log.Event event;
      try {
        event = log.readNext();
      } catch (java.io.EOFException end) {
        break;
      }
      ++events;
      long fingerprint = ByteBuffer.wrap(event.data, 0, 8).getLong();
      Class<?> type = types.getClassByFingerprint(fingerprint);
      check(type != null, "no class for the fingerprint of channel " + event.channel);
      Object message = type.getConstructor(byte[].class).newInstance((Object) event.data);
      if (event.channel.equals("OMNI_STATUS")) {
        check(type.getName().equals("omnipose.status_t"), "OMNI_STATUS holds " + type.getName());
        check(type.getField("source").get(message).equals("file /data/run1 (2 frames)"),
              "status source");
        continue;
      }
      check(event.channel.equals("OMNI_POSE"), "channel " + event.channel);
      check(type.getName().equals("omnipose.pose_t"), "OMNI_POSE holds " + type.getName());
      int k = poses++;
      long sequence = type.getField("sequence").getLong(message);
      byte status = type.getField("status").getByte(message);
      double[] q = (double[]) type.getField("orientation").get(message);
      short used = type.getField("windows_used").getShort(message);
      double angle = 0.1 + 0.2 * k;
      check(sequence == 41 + k, "pose " + k + " sequence " + sequence);
      check(status == type.getField(k == 0 ? "STATUS_OK" : "STATUS_DEGRADED").getByte(null),
            "pose " + k + " status " + status);
      double norm = Math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
      check(Math.abs(norm - 1.0) < 1e-12, "pose " + k + " quaternion norm " + norm);
      check(Math.abs(q[0] - Math.cos(angle / 2)) < 1e-15, "pose " + k + " w " + q[0]);
      for (int i = 0; i < 3; ++i) {
        check(Math.abs(q[i + 1] - Math.sin(angle / 2) * axis[i]) < 1e-15, "pose " + k + " q");
      }
      check(used == 30 + k, "pose " + k + " windows_used " + used);
      System.out.printf("DecodePoseLog: %s: %s sequence %d, status %d, |q| %.15f%n",
                        event.channel, type.getName(), sequence, status, norm);
    }
    check(events == 3 && poses == 2, events + " events, " + poses + " poses");
    System.out.println("DecodePoseLog: 3 events, 2 poses decoded and checked");
  }
}
