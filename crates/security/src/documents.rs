//! The governance and permissions documents sros2 writes by default.
//!
//! Governance: unauthenticated participants refused, discovery and liveliness encrypted,
//! RTPS messages signed, and every topic's data and metadata encrypted with read/write
//! access control. Permissions: sros2's default policy (topics `/*`, services `/*`,
//! publish and subscribe allowed) translated as its `permissions.xsl` does, plus
//! `ros_discovery_info`, which every rmw that publishes the ROS graph needs.

/// The domain governance document for `domain_id`, as sros2's default.
pub fn governance_xml(domain_id: u16) -> String {
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_governance.xsd">
  <domain_access_rules>
    <domain_rule>
      <domains>
        <id>{domain_id}</id>
      </domains>
      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>
      <enable_join_access_control>true</enable_join_access_control>
      <discovery_protection_kind>ENCRYPT</discovery_protection_kind>
      <liveliness_protection_kind>ENCRYPT</liveliness_protection_kind>
      <rtps_protection_kind>SIGN</rtps_protection_kind>
      <topic_access_rules>
        <topic_rule>
          <topic_expression>*</topic_expression>
          <enable_discovery_protection>true</enable_discovery_protection>
          <enable_liveliness_protection>true</enable_liveliness_protection>
          <enable_read_access_control>true</enable_read_access_control>
          <enable_write_access_control>true</enable_write_access_control>
          <metadata_protection_kind>ENCRYPT</metadata_protection_kind>
          <data_protection_kind>ENCRYPT</data_protection_kind>
        </topic_rule>
      </topic_access_rules>
    </domain_rule>
  </domain_access_rules>
</dds>
"#
    )
}

/// The permissions document granting `enclave` (the certificate's CN) the default policy
/// in `domain_id`, valid over the certificate's own validity (ISO 8601, UTC).
pub fn permissions_xml(enclave: &str, domain_id: u16, not_before: &str, not_after: &str) -> String {
    let ros = allow_rule(domain_id, &["rq/*Request", "rr/*Reply", "rt/*"]);
    let graph = allow_rule(domain_id, &["ros_discovery_info"]);
    format!(
        r#"<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_permissions.xsd">
  <permissions>
    <grant name="{enclave}">
      <subject_name>CN={enclave}</subject_name>
      <validity>
        <not_before>{not_before}</not_before>
        <not_after>{not_after}</not_after>
      </validity>
{ros}{graph}      <default>DENY</default>
    </grant>
  </permissions>
</dds>
"#
    )
}

/// One `<allow_rule>` letting the grantee publish and subscribe `topics` in `domain_id`.
fn allow_rule(domain_id: u16, topics: &[&str]) -> String {
    let topics: String = topics
        .iter()
        .map(|t| format!("            <topic>{t}</topic>\n"))
        .collect();
    let access = |kind: &str| {
        format!(
            "        <{kind}>\n          <topics>\n{topics}          </topics>\n        </{kind}>\n"
        )
    };
    format!(
        "      <allow_rule>\n        <domains>\n          <id>{domain_id}</id>\n        </domains>\n{}{}      </allow_rule>\n",
        access("publish"),
        access("subscribe")
    )
}
