// lmf-types.jar as lcm-spy sees it: lcm-spy's own type database
// (lcm.spy.LCMTypeDatabase, which scans the class path) must find every lmf
// type by its fingerprint, which is how it decodes a channel; and a pose2_t
// must survive an encode/decode round trip.
//   java -cp lcm.jar:lmf-types.jar LmfTypesJarCheck.java TYPE...   (e.g. pose2_t)
import java.io.ByteArrayOutputStream;
import java.io.DataInputStream;
import java.io.ByteArrayInputStream;
import java.io.DataOutputStream;

public class LmfTypesJarCheck {
  public static void main(String[] args) throws Exception {
    lcm.spy.LCMTypeDatabase database = new lcm.spy.LCMTypeDatabase();
    int failures = 0;
    for (String type : args) {
      Class<?> cls = Class.forName("lmf." + type);
      long fingerprint = cls.getField("LCM_FINGERPRINT").getLong(null);
      Class<?> found = database.getClassByFingerprint(fingerprint);
      if (found != cls) {
        System.out.println("FAIL: lcm-spy's type database does not find lmf." + type);
        ++failures;
      }
    }
    lmf.pose2_t pose = new lmf.pose2_t();
    pose.x = 1.5;
    pose.y = -2.0;
    pose.phi = 0.25;
    ByteArrayOutputStream bytes = new ByteArrayOutputStream();
    pose.encode(new DataOutputStream(bytes));
    lmf.pose2_t back = new lmf.pose2_t(new DataInputStream(new ByteArrayInputStream(bytes.toByteArray())));
    if (back.x != pose.x || back.y != pose.y || back.phi != pose.phi) {
      System.out.println("FAIL: pose2_t round trip");
      ++failures;
    }
    System.out.println(args.length + " lmf types found by fingerprint, pose2_t round trip ("
                       + bytes.size() + " bytes): " + (failures == 0 ? "ok" : failures + " failures"));
    System.exit(failures == 0 ? 0 : 1);
  }
}
